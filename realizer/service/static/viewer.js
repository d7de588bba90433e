// The browser viewer of the realizer service (protocols/viewer.md, protocols/submitter.md).
// Watches one character's frames over /view (mesh first, then int16 vertex deltas from the
// neutral pose), draws the face with WebGL, and sends BML over /bml (JSON mode), listing the
// feedback. Plain WebGL: no libraries.
"use strict";
(function () {
  const $ = (id) => document.getElementById(id);
  const canvas = $("face");
  const state = {
    mesh: null, positions: null, neutral: null, normals: null, indices: null,
    dirty: false, frames: 0, lastFrame: null, viewer: null, submitter: null,
    submitterCharacter: null, gl: null, program: null, buffers: null, camera: null,
    meshLoaded: false, feedback: [],
  };
  window.realizerViewer = state;  // for tests and for curious users

  function wsBase() {
    return (location.protocol === "https:" ? "wss://" : "ws://") + location.host;
  }
  function query(extra) {
    const params = new URLSearchParams(extra);
    const token = $("token").value;
    if (token) params.set("token", token);
    return params.toString();
  }
  function setStatus(text, ok) {
    const s = $("status");
    s.textContent = text;
    s.className = ok ? "ok" : "bad";
  }

  // -- WebGL --------------------------------------------------------------------------------
  const VERTEX_SHADER = `
    attribute vec3 position; attribute vec3 normal; attribute vec3 colour;
    uniform mat4 projection; uniform mat4 view;
    varying vec3 vNormal; varying vec3 vColour;
    void main() {
      vNormal = normal; vColour = colour;
      gl_Position = projection * view * vec4(position, 1.0);
    }`;
  const FRAGMENT_SHADER = `
    precision mediump float;
    varying vec3 vNormal; varying vec3 vColour;
    void main() {
      vec3 n = normalize(vNormal);
      vec3 key = normalize(vec3(0.3, 0.4, 1.0));
      vec3 fill = normalize(vec3(-0.5, -0.1, 0.6));
      float light = 0.25 + 0.65 * max(dot(n, key), 0.0) + 0.2 * max(dot(n, fill), 0.0);
      gl_FragColor = vec4(vColour * light, 1.0);
    }`;

  function initGl() {
    let gl = canvas.getContext("webgl2", { antialias: true, preserveDrawingBuffer: true });
    if (!gl) {
      gl = canvas.getContext("webgl", { antialias: true, preserveDrawingBuffer: true });
      if (gl && !gl.getExtension("OES_element_index_uint")) gl = null;
    }
    if (!gl) { setStatus("this browser has no WebGL", false); return null; }
    function shader(kind, source) {
      const s = gl.createShader(kind);
      gl.shaderSource(s, source);
      gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
      return s;
    }
    const program = gl.createProgram();
    gl.attachShader(program, shader(gl.VERTEX_SHADER, VERTEX_SHADER));
    gl.attachShader(program, shader(gl.FRAGMENT_SHADER, FRAGMENT_SHADER));
    gl.linkProgram(program);
    gl.useProgram(program);
    state.gl = gl;
    state.program = program;
    state.buffers = { position: gl.createBuffer(), normal: gl.createBuffer(),
                      colour: gl.createBuffer(), index: gl.createBuffer() };
    gl.enable(gl.DEPTH_TEST);
    return gl;
  }

  function perspective(fovy, aspect, near, far) {
    const f = 1 / Math.tan(fovy / 2), nf = 1 / (near - far);
    return new Float32Array([f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1,
                             0, 0, 2 * far * near * nf, 0]);
  }
  function translation(x, y, z) {
    return new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, x, y, z, 1]);
  }

  function computeNormals() {
    const p = state.positions, idx = state.indices, n = state.normals;
    n.fill(0);
    for (let t = 0; t < idx.length; t += 3) {
      const a = idx[t] * 3, b = idx[t + 1] * 3, c = idx[t + 2] * 3;
      const ux = p[b] - p[a], uy = p[b + 1] - p[a + 1], uz = p[b + 2] - p[a + 2];
      const vx = p[c] - p[a], vy = p[c + 1] - p[a + 1], vz = p[c + 2] - p[a + 2];
      const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
      n[a] += nx; n[a + 1] += ny; n[a + 2] += nz;
      n[b] += nx; n[b + 1] += ny; n[b + 2] += nz;
      n[c] += nx; n[c + 1] += ny; n[c + 2] += nz;
    }
  }

  function loadMesh(mesh) {
    const gl = state.gl || initGl();
    if (!gl) return;
    state.mesh = mesh;
    state.neutral = new Float32Array(mesh.neutral.slice().buffer);
    state.positions = state.neutral.slice();
    state.normals = new Float32Array(state.positions.length);
    state.indices = new Uint32Array(mesh.faces.slice().buffer);
    const colours = new Float32Array(mesh.colours.length);
    for (let i = 0; i < colours.length; i++) colours[i] = mesh.colours[i] / 255;
    // Frame the neutral face: centre of its bounding box, far enough to fit its height.
    const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (let i = 0; i < state.neutral.length; i += 3) {
      for (let k = 0; k < 3; k++) {
        lo[k] = Math.min(lo[k], state.neutral[i + k]);
        hi[k] = Math.max(hi[k], state.neutral[i + k]);
      }
    }
    const centre = [0, 1, 2].map((k) => (lo[k] + hi[k]) / 2);
    const size = Math.max(hi[0] - lo[0], hi[1] - lo[1]) * 1.15;
    const fov = 20 * Math.PI / 180;
    const distance = size / 2 / Math.tan(fov / 2) + (hi[2] - lo[2]) / 2;
    state.camera = {
      projection: perspective(fov, canvas.width / canvas.height, distance / 10, distance * 10),
      view: translation(-centre[0], -centre[1], -centre[2] - distance),
    };
    const b = state.buffers;
    gl.bindBuffer(gl.ARRAY_BUFFER, b.colour);
    gl.bufferData(gl.ARRAY_BUFFER, colours, gl.STATIC_DRAW);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, b.index);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, state.indices, gl.STATIC_DRAW);
    state.dirty = true;
    state.meshLoaded = true;
  }

  function applyFrame(frame) {
    state.frames += 1;
    state.lastFrame = { n: frame.n, t: frame.t, character: frame.character,
                        faps: frame.fap ? frame.fap.ids.length : 0 };
    if (!state.positions) return;
    if (frame.vertices) {
      state.positions.set(new Float32Array(frame.vertices.slice().buffer));
    } else {
      state.positions.set(state.neutral);
      if (frame.delta) {
        const ids = new Uint32Array(frame.delta.ids.slice().buffer);
        const q = new Int16Array(frame.delta.q.slice().buffer);
        const step = state.mesh.step;
        for (let i = 0; i < ids.length; i++) {
          const v = ids[i] * 3;
          state.positions[v] += q[3 * i] * step;
          state.positions[v + 1] += q[3 * i + 1] * step;
          state.positions[v + 2] += q[3 * i + 2] * step;
        }
      }
    }
    state.dirty = true;
  }

  function draw() {
    requestAnimationFrame(draw);
    const gl = state.gl;
    if (!gl || !state.dirty || !state.positions) return;
    state.dirty = false;
    computeNormals();
    const b = state.buffers, program = state.program;
    gl.viewport(0, 0, canvas.width, canvas.height);
    gl.clearColor(0.08, 0.08, 0.09, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    const attributes = [["position", b.position, state.positions],
                        ["normal", b.normal, state.normals], ["colour", b.colour, null]];
    for (const [name, buffer, data] of attributes) {
      const location = gl.getAttribLocation(program, name);
      gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
      if (data) gl.bufferData(gl.ARRAY_BUFFER, data, gl.DYNAMIC_DRAW);
      gl.enableVertexAttribArray(location);
      gl.vertexAttribPointer(location, 3, gl.FLOAT, false, 0, 0);
    }
    gl.uniformMatrix4fv(gl.getUniformLocation(program, "projection"), false, state.camera.projection);
    gl.uniformMatrix4fv(gl.getUniformLocation(program, "view"), false, state.camera.view);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, b.index);
    gl.drawElements(gl.TRIANGLES, state.indices.length, gl.UNSIGNED_INT, 0);
    const f = state.lastFrame;
    $("frameinfo").textContent = f
      ? `frame ${f.n}  t=${f.t.toFixed(3)} s  ${f.faps} FAPs set  (${state.frames} received)`
      : "neutral";
  }

  // Where a point of the face (metres) lands on the canvas, in CSS pixels from its top left.
  state.project = function (x, y, z) {
    const c = state.camera, v = c.view, p = c.projection;
    const vx = x + v[12], vy = y + v[13], vz = z + v[14];
    const cx = p[0] * vx, cy = p[5] * vy, cw = -vz;
    return [(cx / cw + 1) / 2 * canvas.clientWidth, (1 - cy / cw) / 2 * canvas.clientHeight];
  };

  // -- the viewer endpoint --------------------------------------------------------------------
  function watch() {
    const character = $("character").value.trim() || "default";
    if (state.viewer) state.viewer.close(1000, "switching character");
    state.meshLoaded = false;
    const ws = new WebSocket(`${wsBase()}/view?${query({ character, fap: "true", vertices: "int16" })}`);
    ws.binaryType = "arraybuffer";
    state.viewer = ws;
    ws.onopen = () => setStatus(`watching ${character}`, true);
    ws.onclose = (event) => {
      if (state.viewer === ws) setStatus(`viewer closed (${event.code} ${event.reason})`, false);
    };
    ws.onmessage = (event) => {
      const message = msgpackDecode(event.data);
      if (message.type === "mesh") loadMesh(message);
      else if (message.type === "frame") applyFrame(message);
      else if (message.type === "error") log("warning", `viewer: ${message.reason}`);
    };
    refreshCharacters();
  }

  // -- the submitter endpoint -----------------------------------------------------------------
  function log(kind, text) {
    const item = document.createElement("li");
    item.className = kind;
    item.textContent = text;
    $("feedback").appendChild(item);
    $("feedback").scrollTop = $("feedback").scrollHeight;
    state.feedback.push({ kind, text });
  }

  function submitter() {
    const character = $("character").value.trim() || "default";
    if (state.submitter && state.submitter.readyState <= 1 && state.submitterCharacter === character) {
      return Promise.resolve(state.submitter);
    }
    if (state.submitter) state.submitter.close(1000, "switching character");
    return new Promise((resolve, reject) => {
      const ws = new WebSocket(`${wsBase()}/bml?${query({ format: "json", character })}`);
      state.submitter = ws;
      state.submitterCharacter = character;
      ws.onmessage = (event) => {
        const m = JSON.parse(event.data);
        if (m.type === "welcome") resolve(ws);
        else if (m.type === "feedback") log(m.kind === "warning" ? "warning" : "feedback", m.xml);
        else if (m.type === "block") log("block", `block ${m.block}: ${m.state} at ${m.time.toFixed(3)} s`);
      };
      ws.onclose = (event) => {
        log("warning", `submitter closed (${event.code} ${event.reason})`);
        reject(new Error(event.reason));
      };
    });
  }

  async function send(message) {
    try {
      const ws = await submitter();
      ws.send(JSON.stringify(message));
    } catch (error) {
      log("warning", `could not send: ${error.message}`);
    }
  }

  async function refreshCharacters() {
    try {
      const health = await (await fetch("/health")).json();
      const list = $("characters");
      list.innerHTML = "";
      for (const id of health.characterIds || []) {
        const option = document.createElement("option");
        option.value = id;
        list.appendChild(option);
      }
    } catch (error) { /* the list is a convenience only */ }
  }

  $("watch").onclick = watch;
  $("send").onclick = () => send({ type: "bml", bml: $("bml").value, character: $("character").value.trim() || "default" });
  $("interrupt").onclick = () => send({ type: "interrupt", block: $("interruptId").value.trim(),
                                        character: $("character").value.trim() || "default" });
  $("clear").onclick = () => { $("feedback").innerHTML = ""; };
  const params = new URLSearchParams(location.search);
  if (params.get("character")) $("character").value = params.get("character");
  if (params.get("token")) $("token").value = params.get("token");
  requestAnimationFrame(draw);
  watch();
})();
