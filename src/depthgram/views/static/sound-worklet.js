// depthgram live viewer: the AudioWorklet that plays the server's live sound.
// The server renders the sound block by block (the live renderer of `depthgram listen`); this
// processor plays what it was sent and tells the page, every few render quanta, how much is left,
// so that the page asks for more as the audio clock consumes it. Nothing is scheduled ahead on a
// clock of its own: after a stall the buffer runs dry (counted) and refills with the newest scene.
"use strict";

const REPORT_QUANTA = 4; // report the buffer level every 4 render quanta (128 frames each)

class LiveSound extends AudioWorkletProcessor {
  constructor() {
    super();
    this.cap = Math.ceil(sampleRate); // one second of stereo, far more than the page keeps
    this.left = new Float32Array(this.cap);
    this.right = new Float32Array(this.cap);
    this.read = 0;
    this.count = 0; // samples buffered
    this.playing = false; // false until the first blocks arrive, and again after a dry spell
    this.startAt = 0; // samples needed to (re)start, set by the page
    this.dry = 0; // times the buffer ran dry while playing
    this.played = 0; // samples played from the server's blocks
    this.quanta = 0;
    this.port.onmessage = (e) => {
      const d = e.data;
      if (d.startAt !== undefined) {
        this.startAt = d.startAt;
        return;
      }
      const pcm = d.pcm; // Float32Array, interleaved stereo
      const n = Math.min(pcm.length / 2, this.cap - this.count);
      let w = (this.read + this.count) % this.cap;
      for (let i = 0; i < n; i++) {
        this.left[w] = pcm[2 * i];
        this.right[w] = pcm[2 * i + 1];
        w = w + 1 === this.cap ? 0 : w + 1;
      }
      this.count += n;
    };
  }

  process(inputs, outputs) {
    const out = outputs[0];
    const n = out[0].length;
    if (!this.playing && this.count >= Math.max(this.startAt, n)) this.playing = true;
    if (this.playing && this.count < n) {
      this.playing = false; // wait for the refill rather than play a stutter
      this.dry += 1;
    }
    if (this.playing) {
      for (let i = 0; i < n; i++) {
        out[0][i] = this.left[this.read];
        if (out.length > 1) out[1][i] = this.right[this.read];
        this.read = this.read + 1 === this.cap ? 0 : this.read + 1;
      }
      this.count -= n;
      this.played += n;
    } else {
      for (const ch of out) ch.fill(0);
    }
    this.quanta += 1;
    if (this.quanta % REPORT_QUANTA === 0) {
      this.port.postMessage({ buffered: this.count, played: this.played, dry: this.dry });
    }
    return true;
  }
}

registerProcessor("depthgram-live-sound", LiveSound);
