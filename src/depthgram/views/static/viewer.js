// depthgram live viewer: draws the frames the server pushes and sends the controls back.
// Plain browser JavaScript, no build step. The server owns the playback; this page only draws,
// acknowledges each frame once drawn (so the server knows when it is behind) and plays sound.
"use strict";

const $ = (id) => document.getElementById(id);
const view = $("view");
const canvas = $("canvas");
const ctx = canvas.getContext("2d");
let name = null;
let socket = null;
let audio = null; // AudioContext at the server's rate, created on the user's click (a gesture)
let audioNode = null; // the AudioWorkletNode playing the server's live blocks (sound-worklet.js)
let audioRate = 22050; // the server's samples per second (hello)
let audioAsked = 0; // samples asked for and not yet received
let audioTotal = 0; // seconds of sound received so far (exposed as data-audio)
// Sound kept buffered ahead of the speaker (s): the delay a new scene adds on its way to the
// ear, and the margin against a server busy sending a frame. The page asks for more as the
// audio clock consumes it, so the speaker's clock, not the server's, paces the synthesis.
const AUDIO_AHEAD_S = 0.08;
const AUDIO_ASK_S = 0.02; // smallest request (s): fewer, larger messages
const shown = []; // arrival times of recent frames, for the displayed rate

function fmt(v, nd = 0) {
  return v === null || v === undefined ? "–" : Number(v).toFixed(nd);
}

function showError(message) {
  $("error").textContent = message || "";
}

async function api(method, path, body) {
  const opts = { method, headers: {} };
  if (body !== undefined) {
    opts.headers["Content-Type"] = "application/json";
    opts.body = JSON.stringify(body);
  }
  const res = await fetch(`/api/recordings/${encodeURIComponent(name)}${path}`, opts);
  const data = await res.json();
  if (!res.ok) {
    showError(data.error || `${res.status}`);
    return null;
  }
  showError("");
  // Only a settings answer refills the form: a late answer to a pause must not undo an edit.
  if (path === "/params") fillParams(data.params);
  // The server answers a pause once the frame in progress is out: that frame is where it stopped.
  if (path === "/pause") view.dataset.pausedAt = String(data.index);
  return data;
}

function fillParams(p) {
  if (!p) return;
  for (const key of ["method", "min_area", "fraction", "bin_mm"]) {
    const el = $(key);
    if (document.activeElement !== el) el.value = p[key];
  }
}

function drawOverlay(msg) {
  const s = msg.drawScale;
  const h = canvas.height;
  const plan = msg.plan || {};
  // The clearance channel: the free columns as a green band; red across the bottom when blocked.
  if (plan.channel) {
    const [c0, c1] = plan.channel.columns;
    ctx.fillStyle = "rgba(60, 220, 90, 0.22)";
    ctx.fillRect(c0 * s, 0, (c1 - c0 + 1) * s, h);
    ctx.strokeStyle = "rgba(60, 220, 90, 0.9)";
    ctx.lineWidth = 2;
    ctx.strokeRect(c0 * s + 1, 1, (c1 - c0 + 1) * s - 2, h - 2);
    ctx.beginPath();
    ctx.moveTo((plan.channel.center_col + 0.5) * s, h);
    ctx.lineTo((plan.channel.center_col + 0.5) * s, h * 0.6);
    ctx.stroke();
    if (plan.channel.free_mm !== null) {
      ctx.font = "bold 12px system-ui, sans-serif";
      ctx.textAlign = "center";
      ctx.textBaseline = "bottom";
      ctx.fillStyle = "rgba(0, 0, 0, 0.65)";
      const label = `free ${fmt(plan.channel.free_mm)} mm`;
      const x = (plan.channel.center_col + 0.5) * s;
      const w = ctx.measureText(label).width + 8;
      ctx.fillRect(x - w / 2, h * 0.6 - 18, w, 16);
      ctx.fillStyle = "#7dff9a";
      ctx.fillText(label, x, h * 0.6 - 3);
    }
  } else if (plan.channel_checked) {
    ctx.fillStyle = "rgba(230, 30, 30, 0.85)";
    ctx.fillRect(0, h - 18, canvas.width, 18);
    ctx.fillStyle = "#ffffff";
    ctx.font = "bold 12px system-ui, sans-serif";
    ctx.textAlign = "center";
    ctx.textBaseline = "middle";
    ctx.fillText("no clear channel", canvas.width / 2, h - 9);
  }
  const actions = {};
  for (const a of plan.actions || []) actions[a.object] = a.action;
  const warned = new Set((plan.warnings || []).map((w) => w.object));
  ctx.font = "bold 12px system-ui, sans-serif";
  ctx.textAlign = "center";
  ctx.textBaseline = "middle";
  for (const o of msg.record.objects) {
    if (warned.has(o.id)) {
      const [x0, y0, x1, y1] = o.bbox_xy;  // half-open: x1, y1 exclusive
      ctx.strokeStyle = "#ff3030";
      ctx.lineWidth = 3;
      ctx.strokeRect(x0 * s, y0 * s, (x1 - x0) * s, (y1 - y0) * s);
    }
    const x = (o.center_xy[0] + 0.5) * s;
    const y = (o.center_xy[1] + 0.5) * s;
    const text = `#${o.id}`;
    const w = ctx.measureText(text).width + 6;
    ctx.fillStyle = "rgba(0, 0, 0, 0.65)";
    ctx.fillRect(x - w / 2, y - 8, w, 16);
    const act = actions[o.id];
    ctx.fillStyle = act === "avoid" ? "#ffb080" : act === "grasp" ? "#a0ff98" : "#ffffff";
    ctx.fillText(text, x, y);
  }
}

function showPanels(msg) {
  const rec = msg.record;
  $("sentence").textContent = rec.sentence;
  const warned = new Set((msg.plan.warnings || []).map((w) => w.object));
  const rows = rec.objects.map((o) => {
    const tr = document.createElement("tr");
    if (warned.has(o.id)) tr.className = "warn";
    const unit = o.v_unit ? ` ${o.v_unit}` : "";
    for (const v of [o.id, o.kind, fmt(o.depth), o.area, o.v_radial === undefined ? "–" : fmt(o.v_radial, 1) + unit,
      o.ttc === undefined ? "–" : fmt(o.ttc, 2), o.status || "–"]) {
      const td = document.createElement("td");
      td.textContent = v;
      tr.appendChild(td);
    }
    return tr;
  });
  $("tracks").tBodies[0].replaceChildren(...rows);
  const ch = msg.plan.channel;
  $("channel").textContent = ch
    ? `Clearance channel: columns ${ch.columns[0]}–${ch.columns[1]}` +
      (ch.angle_deg !== null ? `, heading ${fmt(ch.angle_deg, 1)}°` : "") +
      (ch.width_mm !== null ? `, ${fmt(ch.width_mm)} mm wide` : "") +
      (ch.free_mm !== null ? `, free for ${fmt(ch.free_mm)} mm` : "")
    : msg.plan.channel_checked ? "Clearance channel: blocked" : "Clearance channel: unknown";
  const items = [];
  for (const w of msg.plan.warnings) {
    const li = document.createElement("li");
    li.className = "avoid";
    li.textContent = `WARNING #${w.object}: time to collision ${fmt(w.ttc, 2)} at ${fmt(w.depth_mm)} mm`;
    items.push(li);
  }
  for (const a of msg.plan.actions) {
    const li = document.createElement("li");
    li.className = a.action;
    li.textContent = `${a.action} #${a.object} (${a.kind}, ${fmt(a.distance_mm)} mm): ${a.reason}`;
    items.push(li);
  }
  $("plan").replaceChildren(...items);
  $("tree").replaceChildren(...msg.tree.map((n) => {
    const li = document.createElement("li");
    li.style.paddingLeft = `${n.level * 1.2}em`;
    li.textContent = `${n.kind} #${n.id}` + (n.depth ? `  z=${fmt(n.depth)} mm  A=${n.area}` : "");
    return li;
  }));
}

function showStatus(msg) {
  const now = performance.now();
  shown.push(now);
  while (shown.length && now - shown[0] > 2000) shown.shift();
  const rate = shown.length > 1 ? (1000 * (shown.length - 1)) / (now - shown[0]) : 0;
  const total = msg.frames ? ` / ${msg.frames - 1}` : "";
  const t = msg.time_s === null ? "" : ` · t ${fmt(msg.time_s, 2)} s`;
  const st = $("status");
  st.textContent = `frame ${msg.index}${total}${t} · ${msg.objects} objects · ${fmt(msg.latency_ms, 1)} ms` +
    ` · ${fmt(rate, 1)} frames/s · dropped ${msg.dropped}` +
    (msg.dropped ? ` (server behind ${msg.server_dropped}, page behind ${msg.page_dropped})` : "");
  st.className = msg.dropped ? "dropping" : "";
  view.dataset.objects = String(msg.objects);
  view.dataset.frame = String(msg.index);
  view.dataset.dropped = String(msg.dropped);
  view.dataset.playing = String(msg.playing);
}

function playAudio(msg) {
  if (!audioNode) return;
  const bytes = Uint8Array.from(atob(msg.pcm), (c) => c.charCodeAt(0));
  const pcm16 = new Int16Array(bytes.buffer);
  const pcm = new Float32Array(pcm16.length);
  for (let i = 0; i < pcm16.length; i++) pcm[i] = pcm16[i] / 32768;
  audioAsked = Math.max(0, audioAsked - pcm.length / 2);
  audioTotal += pcm.length / 2 / msg.samplerate;
  audioNode.port.postMessage({ pcm }, [pcm.buffer]);
  view.dataset.audio = audioTotal.toFixed(3);
  view.dataset.audioFrame = String(msg.frame);
}

function askAudio(level) {
  // The worklet's report: ask for what keeps AUDIO_AHEAD_S buffered, counting what is on its way.
  view.dataset.audioPlayed = (level.played / audioRate).toFixed(3);
  view.dataset.audioDry = String(level.dry);
  const need = Math.round(AUDIO_AHEAD_S * audioRate) - level.buffered - audioAsked;
  if (need >= AUDIO_ASK_S * audioRate && socket && socket.readyState === WebSocket.OPEN && $("sound").checked) {
    audioAsked += need;
    socket.send(JSON.stringify({ type: "audio", need }));
  }
}

async function startAudio() {
  audio = new AudioContext({ sampleRate: audioRate });
  await audio.audioWorklet.addModule("/static/sound-worklet.js");
  audioNode = new AudioWorkletNode(audio, "depthgram-live-sound", { outputChannelCount: [2] });
  audioNode.port.onmessage = (e) => askAudio(e.data);
  audioNode.port.postMessage({ startAt: Math.round(0.5 * AUDIO_AHEAD_S * audioRate) });
  audioNode.connect(audio.destination);
}

let colours = null; // 256 RGB triples: index 255 is the near end of the depth range
let last = null; // the frame on screen: {msg, depth, labels, w, h, s}

async function parseFrame(buf) {
  const n = new DataView(buf).getUint32(0, true);
  const msg = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 4, n)));
  let body = buf.slice(4 + n + ((4 - ((4 + n) % 4)) % 4));
  if (msg.compressed) {
    const stream = new Blob([body]).stream().pipeThrough(new DecompressionStream("deflate"));
    body = await new Response(stream).arrayBuffer();
  }
  const [w, h] = msg.size;
  const depth = new Uint16Array(body, 0, w * h);
  // Typed arrays need an offset that is a multiple of their element size: 2 w h is one of 4 only
  // when w h is even, so a uint32 image is copied out.
  const labels = msg.labels_dtype === "uint8" ? new Uint8Array(body, 2 * w * h, w * h)
    : msg.labels_dtype === "uint16" ? new Uint16Array(body, 2 * w * h, w * h)
      : new Uint32Array(body.slice(2 * w * h), 0, w * h);
  return { msg, depth, labels, w, h };
}

// The depth in colour (near warm, far cool, invalid black) with white one-pixel outlines where the
// object id changes, drawn at the display scale so that outlines stay thin on small frames.
// One pass over the pixels with 32-bit writes: this loop is most of the page's time per frame.
let lut = null; // colours as little-endian RGBA words
let image = null; // reused ImageData of the display size
function drawDepth(f, s) {
  const { depth, labels, w, h } = f;
  const [lo, hi] = f.msg.depth_range_mm;
  const W = w * s;
  if (!lut) {
    lut = new Uint32Array(256);
    for (let i = 0; i < 256; i++) {
      const [r, g, b] = colours[i];
      lut[i] = ((255 << 24) | (b << 16) | (g << 8) | r) >>> 0;
    }
  }
  if (!image || image.width !== W || image.height !== h * s) image = ctx.createImageData(W, h * s);
  const px = new Uint32Array(image.data.buffer);
  const k = 255 / Math.max(hi - lo, 1e-6);
  const WHITE = 0xffffffff;
  for (let y = 0; y < h; y++) {
    const r0 = y * w;
    for (let x = 0; x < w; x++) {
      const i = r0 + x;
      const d = depth[i];
      let c = 0xff000000;
      if (d > 0) {
        let t = ((d - lo) * k) | 0;
        t = t < 0 ? 0 : t > 255 ? 255 : t;
        c = lut[255 - t];
      }
      const l = labels[i];
      if (s === 1) {
        // Outline pixels: inside an object, next to another id on the right or below.
        px[i] = l > 0 && ((x + 1 < w && labels[i + 1] !== l) || (y + 1 < h && labels[i + w] !== l)) ? WHITE : c;
        continue;
      }
      const left = l > 0 && x > 0 && labels[i - 1] !== l;
      const up = l > 0 && y > 0 && labels[i - w] !== l;
      for (let dy = 0; dy < s; dy++) {
        const row = (y * s + dy) * W + x * s;
        for (let dx = 0; dx < s; dx++) px[row + dx] = (left && dx === 0) || (up && dy === 0) ? WHITE : c;
      }
    }
  }
  ctx.putImageData(image, 0, 0);
}

let barStrip = null; // ImageData of the colour bar's strip of colours
function drawColourBar(msg) {
  const bar = $("colourbar");
  const g = bar.getContext("2d");
  const [lo, hi] = msg.depth_range_mm;
  const H = bar.height;
  const top = 8, bottom = H - 8, x0 = 4, bw = 14;
  g.clearRect(0, 0, bar.width, H);
  if (!barStrip || barStrip.height !== bottom - top) {
    // the strip of colours depends only on the bar's height: built once, copied each time
    barStrip = g.createImageData(bw, bottom - top);
    const px = new Uint32Array(barStrip.data.buffer);
    for (let y = 0; y < bottom - top; y++) {
      const t = y / (bottom - top - 1); // top = near (lo), bottom = far (hi)
      const [r, gr, b] = colours[Math.round(255 * (1 - t))];
      px.fill(((255 << 24) | (b << 16) | (gr << 8) | r) >>> 0, y * bw, (y + 1) * bw);
    }
  }
  g.putImageData(barStrip, x0, top);
  g.fillStyle = "#e6e6e6";
  g.font = "11px system-ui, sans-serif";
  g.textBaseline = "middle";
  g.textAlign = "left";
  const step = niceStep((hi - lo) / 5);
  for (let v = Math.ceil(lo / step) * step; v <= hi; v += step) {
    const y = top + ((v - lo) / (hi - lo)) * (bottom - top - 1);
    g.fillRect(x0 + bw, y, 4, 1);
    g.fillText(`${Math.round(v)}`, x0 + bw + 6, y);
  }
  bar.dataset.lo = String(lo);
  bar.dataset.hi = String(hi);
  bar.title = `depth colour scale: ${fmt(lo)}–${fmt(hi)} mm (1st–99th percentile of the frame)`;
}

function niceStep(raw) {
  const p = Math.pow(10, Math.floor(Math.log10(Math.max(raw, 1e-9))));
  for (const m of [1, 2, 5, 10]) if (m * p >= raw) return m * p;
  return 10 * p;
}

function showHover(ev) {
  if (!last) return;
  const r = canvas.getBoundingClientRect();
  const x = Math.floor(((ev.clientX - r.left) * canvas.width) / r.width / last.s);
  const y = Math.floor(((ev.clientY - r.top) * canvas.height) / r.height / last.s);
  if (x < 0 || y < 0 || x >= last.w || y >= last.h) return;
  const i = y * last.w + x;
  const d = last.depth[i];
  const id = last.labels[i];
  const o = last.msg.record.objects.find((q) => q.id === id);
  const obj = o ? ` · object #${o.id} (${o.kind}, ${fmt(o.depth)} mm)` : id ? ` · #${id}` : " · no object";
  $("hover").textContent = `x ${x}, y ${y} · ${d ? `${d} mm` : "no depth"}${obj}`;
  view.dataset.hoverDepth = String(d);
  view.dataset.hoverObject = String(o ? o.id : id || "");
}

function showTimeline(msg) {
  const tl = $("timeline");
  if (!msg.frames) {
    tl.disabled = true;
    return;
  }
  tl.max = String(msg.frames - 1);
  if (!tl.matches(":active")) tl.value = String(msg.index);
  $("position").textContent = `${msg.index} / ${msg.frames - 1}`;
}

// The text panels and the colour bar's scale are redrawn at most every PANEL_MS while playing:
// nobody reads a table 30 times a second, and re-laying them out for every frame cost the page
// more than drawing the picture (benchmarks/bench_viewer.py prints the browser's CPU time per
// frame). A paused, stepped or sought frame, and the last one played, are always shown in full.
const PANEL_MS = 250;
let panelsAt = -Infinity; // when the panels were last redrawn (performance.now(), ms)
let panelsDue = null; // timer that shows the newest frame's panels once PANEL_MS has passed
let panelsMsg = null; // the newest frame not yet shown in the panels

function flushText() {
  panelsDue = null;
  if (!panelsMsg) return;
  const msg = panelsMsg;
  panelsMsg = null;
  panelsAt = performance.now();
  drawColourBar(msg);
  showPanels(msg);
}

function showText(msg) {
  panelsMsg = msg;
  const wait = PANEL_MS - (performance.now() - panelsAt);
  if (!msg.playing || wait <= 0) {
    if (panelsDue !== null) clearTimeout(panelsDue);
    flushText();
  } else if (panelsDue === null) {
    panelsDue = setTimeout(flushText, wait);
  }
}

async function onFrame(buf) {
  const t0 = performance.now();
  const f = await parseFrame(buf);
  const msg = f.msg;
  // Small sensors (176 x 132) are drawn at twice the server's minimum scale; the ids and the
  // channel are drawn at that size too, so that text stays sharp.
  const s = msg.scale * (f.w * msg.scale < 480 ? 2 : 1);
  if (canvas.width !== s * f.w || canvas.height !== s * f.h) {
    canvas.width = s * f.w;
    canvas.height = s * f.h;
    $("colourbar").height = canvas.height;
  }
  f.s = s;
  view.dataset.ended = "false";
  drawDepth(f, s);
  msg.drawScale = s;
  drawOverlay(msg);
  last = f;
  showText(msg);
  showStatus(msg);
  showTimeline(msg);
  if ($("show3d").checked) cloud.draw(f);
  socket.send(JSON.stringify({ type: "ack", index: msg.index }));
  window.__depthgramShown = (window.__depthgramShown || 0) + 1;
  (window.__depthgramDrawMs = window.__depthgramDrawMs || []).push(performance.now() - t0);
}

function download(blob, filename) {
  const a = document.createElement("a");
  a.href = URL.createObjectURL(blob);
  a.download = filename;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 10000);
}

function snapshot() {
  if (!last) return;
  const m = last.msg;
  const base = `${name}_frame${String(m.index).padStart(6, "0")}`;
  canvas.toBlob((png) => download(png, `${base}.png`), "image/png");
  const keep = { index: m.index, time_s: m.time_s, size: m.size, depth_range_mm: m.depth_range_mm,
    intrinsics: m.intrinsics, record: m.record, plan: m.plan, tree: m.tree };
  download(new Blob([JSON.stringify(keep, null, 2)], { type: "application/json" }), `${base}.json`);
}

function connect() {
  const proto = location.protocol === "https:" ? "wss" : "ws";
  socket = new WebSocket(`${proto}://${location.host}/ws/${encodeURIComponent(name)}`);
  socket.binaryType = "arraybuffer";
  socket.onmessage = (ev) => {
    if (ev.data instanceof ArrayBuffer) {
      onFrame(ev.data).catch((e) => {
        showError(`cannot draw the frame: ${e}`);
        socket.send(JSON.stringify({ type: "ack" }));
      });
      return;
    }
    const msg = JSON.parse(ev.data);
    if (msg.type === "hello") {
      $("recording").textContent = `${msg.name}${msg.frames ? ` · ${msg.frames} frames` : ""} · ${fmt(msg.fps, 1)} frames/s`;
      if (![...$("speed").options].some((o) => Number(o.value) === msg.speed)) {
        $("speed").add(new Option(`${msg.speed}×`, String(msg.speed)));
      }
      $("speed").value = String(msg.speed);
      // The methods the installed segmentation offers, not a list frozen into the page.
      $("method").replaceChildren(...msg.methods.map((m) => new Option(m, m)));
      fillParams(msg.params);
      if (!msg.sound_available) $("sound").disabled = true;
      if (msg.samplerate) audioRate = msg.samplerate;
      colours = msg.colours;
      if (msg.frames) $("timeline").max = String(msg.frames - 1);
    } else if (msg.type === "audio") {
      playAudio(msg);
    } else if (msg.type === "error") {
      showError(msg.message);
    } else if (msg.type === "end") {
      $("status").textContent += " · end of recording";
      view.dataset.ended = "true";
    }
  };
  socket.onclose = () => {
    $("status").textContent = "disconnected: is the server still running?";
  };
}

$("play").onclick = () => api("POST", "/play");
$("pause").onclick = () => api("POST", "/pause");
$("step").onclick = () => api("POST", "/step");
$("back").onclick = () => {
  if (last && last.msg.index > 0) api("POST", "/seek", { index: last.msg.index - 1 });
};
$("timeline").onchange = () => api("POST", "/seek", { index: Number($("timeline").value) });
$("timeline").oninput = () => {
  $("position").textContent = `${$("timeline").value} / ${$("timeline").max}`;
};
$("snapshot").onclick = snapshot;
canvas.addEventListener("mousemove", showHover);
$("show3d").onchange = () => {
  $("cloud").hidden = !$("show3d").checked;
  if ($("show3d").checked && last) cloud.draw(last);
};
$("speed").onchange = () => api("PUT", "/speed", { value: Number($("speed").value) });
$("apply").onclick = () => {
  const params = { method: $("method").value };
  for (const key of ["min_area", "fraction", "bin_mm"]) {
    if ($(key).value !== "") params[key] = Number($(key).value);
  }
  api("PUT", "/params", params);
};
$("sound").onchange = async () => {
  const on = $("sound").checked;
  socket.send(JSON.stringify({ type: "sound", on }));
  audioAsked = 0;
  try {
    if (on && !audio) await startAudio();
    if (audio) await (on ? audio.resume() : audio.suspend());
  } catch (e) {
    showError(`sound cannot play in this browser: ${e}`);
  }
};

fetch("/api/recordings")
  .then((r) => r.json())
  .then((data) => {
    name = data.recordings[0].name;
    connect();
  })
  .catch((e) => showError(`cannot reach the server: ${e}`));
