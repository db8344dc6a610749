// depthgram live viewer: the frame as a 3-D point cloud coloured by object, in plain WebGL 1.
// Written by hand rather than vendoring three.js: one draw call of GL_POINTS with one matrix is
// all it needs (about 150 lines), and there is nothing to keep up to date or license.
// Drag to turn the cloud, wheel to move closer. Camera frame: x right, y down, z forward (mm).
"use strict";

const cloud = (() => {
  const el = document.getElementById("cloud");
  let gl = null;
  let prog = null;
  let posBuf = null;
  let colBuf = null;
  let count = 0;
  let centre = [0, 0, 0];
  let dist = 3000; // mm from the centre of the cloud to the eye
  let placed = false;
  let yaw = 0;
  let pitch = 0.35;
  const HFOV_DEG = 57; // assumed when the recording gives no intrinsics (Kinect-class sensors)

  const VS = `attribute vec3 p; attribute vec3 c; uniform mat4 m; varying vec3 v;
    void main() { gl_Position = m * vec4(p, 1.0); gl_PointSize = 2.0; v = c; }`;
  const FS = `precision mediump float; varying vec3 v; void main() { gl_FragColor = vec4(v, 1.0); }`;

  function init() {
    if (gl) return true;
    gl = el.getContext("webgl", { preserveDrawingBuffer: true, antialias: false });
    if (!gl) {
      el.dataset.error = "WebGL is not available in this browser";
      return false;
    }
    const shader = (type, src) => {
      const sh = gl.createShader(type);
      gl.shaderSource(sh, src);
      gl.compileShader(sh);
      return sh;
    };
    prog = gl.createProgram();
    gl.attachShader(prog, shader(gl.VERTEX_SHADER, VS));
    gl.attachShader(prog, shader(gl.FRAGMENT_SHADER, FS));
    gl.linkProgram(prog);
    posBuf = gl.createBuffer();
    colBuf = gl.createBuffer();
    el.addEventListener("mousemove", (ev) => {
      if (!(ev.buttons & 1)) return;
      yaw += ev.movementX * 0.01;
      pitch = Math.max(-1.5, Math.min(1.5, pitch + ev.movementY * 0.01));
      render();
    });
    el.addEventListener("wheel", (ev) => {
      ev.preventDefault();
      dist = Math.max(100, dist * Math.exp(ev.deltaY * 0.001));
      render();
    }, { passive: false });
    return true;
  }

  // Distinct colours for ids (golden-ratio hues); grey for pixels outside every object.
  function colourOf(id) {
    if (!id) return [0.5, 0.5, 0.5];
    const h = (id * 0.618033988749895) % 1;
    const f = (n) => {
      const k = (n + h * 6) % 6;
      return 0.95 - 0.95 * 0.75 * Math.max(0, Math.min(k, 4 - k, 1));
    };
    return [f(5), f(3), f(1)];
  }

  function build(f) {
    const { depth, labels, w, h } = f;
    const k = f.msg.intrinsics;
    const fx = k ? k.fx : w / 2 / Math.tan((HFOV_DEG * Math.PI) / 360);
    const fy = k ? k.fy : fx;
    const cx = k ? k.cx : (w - 1) / 2;
    const cy = k ? k.cy : (h - 1) / 2;
    const stride = Math.max(1, Math.ceil(Math.sqrt((w * h) / 120000))); // at most ~120k points
    const pos = new Float32Array(Math.ceil(w / stride) * Math.ceil(h / stride) * 3);
    const col = new Float32Array(pos.length);
    let n = 0;
    let sx = 0, sy = 0, sz = 0;
    for (let y = 0; y < h; y += stride) {
      for (let x = 0; x < w; x += stride) {
        const z = depth[y * w + x];
        if (!z) continue;
        const X = ((x - cx) * z) / fx;
        const Y = ((y - cy) * z) / fy;
        pos.set([X, Y, z], 3 * n);
        col.set(colourOf(labels[y * w + x]), 3 * n);
        sx += X; sy += Y; sz += z;
        n++;
      }
    }
    count = n;
    if (n) centre = [sx / n, sy / n, sz / n];
    if (!placed && n) {
      dist = Math.max(500, 1.2 * centre[2]); // the user's zoom is kept from then on
      placed = true;
    }
    gl.bindBuffer(gl.ARRAY_BUFFER, posBuf);
    gl.bufferData(gl.ARRAY_BUFFER, pos.subarray(0, 3 * n), gl.DYNAMIC_DRAW);
    gl.bindBuffer(gl.ARRAY_BUFFER, colBuf);
    gl.bufferData(gl.ARRAY_BUFFER, col.subarray(0, 3 * n), gl.DYNAMIC_DRAW);
    el.dataset.points = String(n);
    el.dataset.intrinsics = k ? "recording" : `assumed ${HFOV_DEG}° horizontal field of view`;
  }

  // Column-major 4x4 products, as WebGL expects.
  function mul(a, b) {
    const o = new Float32Array(16);
    for (let i = 0; i < 4; i++)
      for (let j = 0; j < 4; j++)
        for (let q = 0; q < 4; q++) o[j * 4 + i] += a[q * 4 + i] * b[j * 4 + q];
    return o;
  }

  function matrix() {
    const aspect = el.width / el.height;
    const near = 10, far = 1e5, t = 1 / Math.tan((50 * Math.PI) / 360);
    const proj = new Float32Array([t / aspect, 0, 0, 0, 0, t, 0, 0, 0, 0, (far + near) / (near - far), -1,
      0, 0, (2 * far * near) / (near - far), 0]);
    const cyw = Math.cos(yaw), syw = Math.sin(yaw), cp = Math.cos(pitch), sp = Math.sin(pitch);
    // Camera frame (y down, z forward) to GL's (y up, z towards the eye), turned about the centre.
    const flip = new Float32Array([1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1]);
    const toCentre = new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -centre[0], -centre[1], -centre[2], 1]);
    const rotY = new Float32Array([cyw, 0, -syw, 0, 0, 1, 0, 0, syw, 0, cyw, 0, 0, 0, 0, 1]);
    const rotX = new Float32Array([1, 0, 0, 0, 0, cp, sp, 0, 0, -sp, cp, 0, 0, 0, 0, 1]);
    const back = new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, -dist, 1]);
    return mul(proj, mul(back, mul(rotX, mul(rotY, mul(flip, toCentre)))));
  }

  function render() {
    if (!gl) return;
    gl.viewport(0, 0, el.width, el.height);
    gl.clearColor(20 / 255, 23 / 255, 26 / 255, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    gl.useProgram(prog);
    gl.uniformMatrix4fv(gl.getUniformLocation(prog, "m"), false, matrix());
    for (const [name, buf] of [["p", posBuf], ["c", colBuf]]) {
      const loc = gl.getAttribLocation(prog, name);
      gl.bindBuffer(gl.ARRAY_BUFFER, buf);
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, 3, gl.FLOAT, false, 0, 0);
    }
    gl.drawArrays(gl.POINTS, 0, count);
    el.dataset.frame = String(el.dataset.pending);
  }

  // Pixels of the drawing that are not background: what a test can check was really drawn.
  function coverage() {
    if (!gl) return 0;
    const px = new Uint8Array(el.width * el.height * 4);
    gl.readPixels(0, 0, el.width, el.height, gl.RGBA, gl.UNSIGNED_BYTE, px);
    let n = 0;
    for (let i = 0; i < px.length; i += 4) if (px[i] !== 20 || px[i + 1] !== 23 || px[i + 2] !== 26) n++;
    return n;
  }

  return {
    draw(f) {
      if (!init()) return;
      el.dataset.pending = String(f.msg.index);
      build(f);
      render();
    },
    coverage,
    colourOf,
  };
})();
