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
let audio = null; // AudioContext, created on the user's click (browsers require a gesture)
let audioNext = 0; // time at which the next audio chunk starts (s, AudioContext clock)
let audioTotal = 0; // seconds of sound scheduled so far (exposed as data-audio)
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

function playAudio(a) {
  if (!audio || !a) return;
  for (const chunk of a.chunks) {
    const bytes = Uint8Array.from(atob(chunk), (c) => c.charCodeAt(0));
    const pcm = new Int16Array(bytes.buffer);
    const n = pcm.length / a.channels;
    if (n < 1) continue;
    const buf = audio.createBuffer(a.channels, n, a.samplerate);
    for (let c = 0; c < a.channels; c++) {
      const out = buf.getChannelData(c);
      for (let i = 0; i < n; i++) out[i] = pcm[i * a.channels + c] / 32768;
    }
    const src = audio.createBufferSource();
    src.buffer = buf;
    src.connect(audio.destination);
    // Chunks are queued back to back; after a stall restart a little ahead to avoid clicks.
    audioNext = Math.max(audioNext, audio.currentTime + 0.05);
    src.start(audioNext);
    audioNext += buf.duration;
    audioTotal += buf.duration;
    view.dataset.audio = audioTotal.toFixed(3);
  }
}

function onFrame(msg) {
  const img = new Image();
  img.onload = () => {
    // Small sensors (176 x 132) are drawn at twice the sent picture; the ids and the channel
    // are drawn at that size too, so that text stays sharp.
    const k = img.naturalWidth < 480 ? 2 : 1;
    if (canvas.width !== k * img.naturalWidth || canvas.height !== k * img.naturalHeight) {
      canvas.width = k * img.naturalWidth;
      canvas.height = k * img.naturalHeight;
    }
    ctx.imageSmoothingEnabled = false;
    ctx.drawImage(img, 0, 0, canvas.width, canvas.height);
    msg.drawScale = msg.scale * k;
    drawOverlay(msg);
    showPanels(msg);
    showStatus(msg);
    playAudio(msg.audio);
    socket.send(JSON.stringify({ type: "ack", index: msg.index }));
  };
  img.onerror = () => socket.send(JSON.stringify({ type: "ack", index: msg.index }));
  img.src = msg.image;
}

function connect() {
  const proto = location.protocol === "https:" ? "wss" : "ws";
  socket = new WebSocket(`${proto}://${location.host}/ws/${encodeURIComponent(name)}`);
  socket.onmessage = (ev) => {
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
    } else if (msg.type === "frame") {
      onFrame(msg);
    } else if (msg.type === "error") {
      showError(msg.message);
    } else if (msg.type === "end") {
      $("status").textContent += " · end of recording";
    }
  };
  socket.onclose = () => {
    $("status").textContent = "disconnected: is the server still running?";
  };
}

$("play").onclick = () => api("POST", "/play");
$("pause").onclick = () => api("POST", "/pause");
$("step").onclick = () => api("POST", "/step");
$("speed").onchange = () => api("PUT", "/speed", { value: Number($("speed").value) });
$("apply").onclick = () => {
  const params = { method: $("method").value };
  for (const key of ["min_area", "fraction", "bin_mm"]) {
    if ($(key).value !== "") params[key] = Number($(key).value);
  }
  api("PUT", "/params", params);
};
$("sound").onchange = () => {
  const on = $("sound").checked;
  if (on && !audio) audio = new AudioContext();
  if (audio) (on ? audio.resume() : audio.suspend());
  audioNext = 0;
  socket.send(JSON.stringify({ type: "sound", on }));
};

fetch("/api/recordings")
  .then((r) => r.json())
  .then((data) => {
    name = data.recordings[0].name;
    connect();
  })
  .catch((e) => showError(`cannot reach the server: ${e}`));
