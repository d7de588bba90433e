// The browser viewer of the realizer service (protocols/viewer.md, protocols/submitter.md),
// on three.js. Each watched character has its own /view connection; the face's deformation
// model arrives once (`model=true`) and the GPU deforms the face from the FAPs of each frame
// (facemodel.js: the same arrays the server's deform() evaluates). Orbit, zoom and pan with
// the mouse; several characters side by side; one-click examples; a timeline of each block's
// behaviours and sync points as they fire; interrupt buttons; speech audio through Web Audio.
import * as THREE from "three";
import { OrbitControls } from "three/addons/OrbitControls.js";
import * as fm from "/static/facemodel.js";
import { FapStreamDecoder, decodeArkit, ARKIT_NAMES } from "/static/fapcodec.js";
import { AudioPlayer } from "/static/audio.js";
import {
  SubmitClient, ViewClient, Unauthorized, Forbidden, ServerBusy, ServerUnavailable, ConnectionLost,
} from "/static/realizer-client.js";

const $ = (id) => document.getElementById(id);
const canvas = $("face");
const SPACING_M = 0.26;  // between characters side by side

const state = {
  meshLoaded: false, frames: 0, lastFrame: null, feedback: [], characters: new Map(),
  submitter: null, blocks: new Map(), gpu: false, decoded: [], errors: [],
  stream: "fap", audio: null, avatar: null, drawn: [],
};
window.realizerViewer = state;  // for tests and for curious users

function wsBase() { return (location.protocol === "https:" ? "wss://" : "ws://") + location.host; }
function token() { return $("token").value; }
function setStatus(text, ok) { const s = $("status"); s.textContent = text; s.className = ok ? "ok" : "bad"; }

// -- plain words for refused connections ---------------------------------------------------

// The client module (realizer-client.js) turns a refused handshake into Unauthorized (401)
// or Forbidden (403), a limit into ServerBusy or ConnectionLost with the server's reason.
function plainWords(error, path) {
  if (error instanceof Unauthorized) {
    return token()
      ? "the server refused this token: check it and press Watch again"
      : "this server needs a token: enter it in the token box and press Watch again";
  }
  if (error instanceof Forbidden) {
    return path === "/bml"
      ? "this token may only watch; sending BML needs a submit token"
      : "this token may not watch";
  }
  if (error instanceof ServerBusy) return `the server is busy: ${error.reason || "try again later"}`;
  if (error instanceof ConnectionLost) {
    if (error.code === 1008) return `the server refused: ${error.reason || "a limit was reached"}`;
    if (error.code === 1001) return "the server is shutting down";
    if (error.code === 1000) return "closed";
    return error.reason ? `closed: ${error.reason}` : "the connection was lost";
  }
  if (error instanceof ServerUnavailable) return "the server cannot be reached (is it running?)";
  return String(error && error.message ? error.message : error);
}

// -- three.js scene ---------------------------------------------------------------------------

const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.setSize(canvas.clientWidth, canvas.clientHeight, false);
renderer.outputColorSpace = THREE.SRGBColorSpace;
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x141517);
const camera = new THREE.PerspectiveCamera(28, canvas.clientWidth / canvas.clientHeight, 0.01, 20);
camera.position.set(0, 0, 0.75);
const controls = new OrbitControls(camera, canvas);
controls.enableDamping = false;
controls.addEventListener("change", () => { state.dirty = true; });
scene.add(new THREE.HemisphereLight(0xfff4e8, 0x30343a, 1.1));
const key = new THREE.DirectionalLight(0xffffff, 2.0);
key.position.set(0.5, 0.7, 1.2);
scene.add(key);
const fill = new THREE.DirectionalLight(0xbcd4ff, 0.6);
fill.position.set(-0.9, 0.1, 0.6);
scene.add(fill);
const rim = new THREE.DirectionalLight(0xffffff, 0.5);
rim.position.set(0, 0.5, -1);
scene.add(rim);

function dataTexture({ data, width, height }) {
  const t = new THREE.DataTexture(data, width, height, THREE.RGBAFormat, THREE.FloatType);
  t.minFilter = THREE.NearestFilter; t.magFilter = THREE.NearestFilter;
  t.generateMipmaps = false; t.needsUpdate = true;
  return t;
}

// Where each character stands, along x: at its eyes' x in the server's scene (the scene
// message, protocols/viewer.md), so characters that gaze at each other are drawn looking at
// each other; before the scene is known, SPACING_M apart. The avatar (if any) takes the
// next place. Centred on the watched characters.
function places() {
  const ids = [...state.characters.keys()];
  const targets = state.scene ? state.scene.targets : null;
  let xs;
  if (targets && ids.every((id) => targets[id])) {
    xs = ids.map((id) => targets[id][0]);
    if (state.avatar) xs.push((xs.length ? Math.max(...xs) : 0) + state.scene.spacing);
  } else {
    const count = ids.length + (state.avatar ? 1 : 0);
    xs = [...Array(count).keys()].map((i) => i * SPACING_M);
  }
  const mid = xs.length ? (Math.min(...xs) + Math.max(...xs)) / 2 : 0;
  return xs.map((x) => x - mid);
}

function layout() {
  const xs = places();
  let i = 0;
  for (const c of state.characters.values()) {
    if (c.group) c.group.position.x = xs[i];
    i++;
  }
  if (state.avatar) state.avatar.root.position.x = xs[i];
  state.width = xs.length ? Math.max(...xs) - Math.min(...xs) : 0;
  state.dirty = true;
}

function onScene(m) {
  const ids = m.characters || [];
  // the distance between neighbours in the scene, for the avatar's place
  const xs = ids.map((id) => (m.targets[id] || [0])[0]).sort((a, b) => a - b);
  let spacing = SPACING_M;
  for (let i = 1; i < xs.length; i++) spacing = Math.max(spacing, xs[i] - xs[i - 1]);
  const before = state.width;
  state.scene = { version: m.version, characters: ids, targets: m.targets, spacing };
  layout();
  const first = state.characters.values().next().value;
  if (first && first.neutral && state.width !== before) frameCamera(first.neutral);
}
state.layout = () => {
  layout();
  const first = state.characters.values().next().value;
  if (first && first.neutral) frameCamera(first.neutral);
};

// Build (or rebuild) a character's mesh from its mesh message, and its GPU deformation when
// the model message has come. Without WebGL2 float textures it deforms in JavaScript.
function buildMesh(c) {
  if (c.group) scene.remove(c.group);
  const mesh = c.mesh;
  const neutral = new Float32Array(mesh.neutral.slice().buffer);
  const faces = new Uint32Array(mesh.faces.slice().buffer);
  const colours = new Uint8Array(mesh.colours.slice().buffer);
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute("position", new THREE.BufferAttribute(neutral.slice(), 3));
  const linear = new Float32Array(colours.length);
  const tmp = new THREE.Color();
  for (let i = 0; i < colours.length; i += 3) {
    tmp.setRGB(colours[i] / 255, colours[i + 1] / 255, colours[i + 2] / 255, THREE.SRGBColorSpace);
    linear[i] = tmp.r; linear[i + 1] = tmp.g; linear[i + 2] = tmp.b;
  }
  geometry.setAttribute("color", new THREE.BufferAttribute(linear, 3));
  geometry.setIndex(new THREE.BufferAttribute(faces, 1));
  geometry.computeVertexNormals();
  const material = new THREE.MeshStandardMaterial({ vertexColors: true, roughness: 0.62, metalness: 0 });
  c.neutral = neutral;
  c.geometry = geometry;
  c.gpu = false;
  if (c.model && renderer.capabilities.isWebGL2) {
    const arrays = fm.gpuArrays(c.model);
    geometry.setAttribute("rzRange", new THREE.BufferAttribute(arrays.range, 4));
    const frame = fm.frameArrays(c.model, c.faps);
    c.textures = {
      rzEntries: dataTexture(arrays.entries), rzLinks: dataTexture(arrays.links),
      rzAmounts: dataTexture(frame.amounts), rzMaps: dataTexture(frame.maps),
    };
    material.flatShading = true;  // normals from the deformed surface (screen derivatives)
    material.onBeforeCompile = (shader) => {
      for (const [name, texture] of Object.entries(c.textures)) shader.uniforms[name] = { value: texture };
      shader.uniforms.rzGroupCount = { value: c.model.groupCount };
      shader.vertexShader = fm.GLSL_DEFORM + shader.vertexShader.replace(
        "#include <begin_vertex>", "vec3 transformed = rzDeform(position);");
    };
    material.customProgramCacheKey = () => "realizer-gpu-deform";
    c.gpu = true;
  }
  const object = new THREE.Mesh(geometry, material);
  object.frustumCulled = false;
  c.object = object;
  c.group = new THREE.Group();
  c.group.add(object);
  scene.add(c.group);
  layout();
  state.dirty = true;
  if (state.characters.size === 1 || !state.framed) frameCamera(neutral);
  state.gpu = [...state.characters.values()].every((x) => x.gpu);
}

function frameCamera(neutral) {
  const box = new THREE.Box3().setFromBufferAttribute(new THREE.BufferAttribute(neutral, 3));
  const centre = box.getCenter(new THREE.Vector3());
  const size = box.getSize(new THREE.Vector3()).length();
  controls.target.copy(centre);
  const count = state.characters.size + (state.avatar ? 1 : 0);
  controls.target.x = 0;
  // far enough back for one face, or for the whole row (the vertical field of view is
  // 28 degrees; the row's width over the aspect ratio, with a face's width of margin)
  const aspect = camera.aspect || 1;
  const row = ((state.width || 0) + size) / aspect / (2 * Math.tan((14 * Math.PI) / 180));
  camera.position.set(0, centre.y, centre.z + Math.max(size * 1.55 * Math.max(1, count * 0.7), row));
  camera.near = size / 100; camera.far = size * 50;
  camera.updateProjectionMatrix();
  controls.update();
  state.framed = true;
}

// A frame's FAPs (FAP n at n-1) into the character's face.
function applyFaps(c, faps) {
  c.faps = faps;
  if (c.gpu) {
    const frame = fm.frameArrays(c.model, faps);
    c.textures.rzAmounts.image.data.set(frame.amounts.data);
    c.textures.rzAmounts.needsUpdate = true;
    c.textures.rzMaps.image.data.set(frame.maps.data);
    c.textures.rzMaps.needsUpdate = true;
  } else if (c.model) {
    c.geometry.attributes.position.array.set(fm.deformCPU(c.model, faps));
    c.geometry.attributes.position.needsUpdate = true;
    c.geometry.computeVertexNormals();
  }
}

// The vertex-delta fallback for servers that send no model.
function applyDelta(c, frame) {
  if (c.model || !frame.delta) return;
  const positions = c.geometry.attributes.position.array;
  positions.set(c.neutral);
  const ids = new Uint32Array(frame.delta.ids.slice().buffer);
  const q = new Int16Array(frame.delta.q.slice().buffer);
  for (let i = 0; i < ids.length; i++) {
    for (let k = 0; k < 3; k++) positions[ids[i] * 3 + k] += q[3 * i + k] * c.mesh.step;
  }
  c.geometry.attributes.position.needsUpdate = true;
  c.geometry.computeVertexNormals();
}

// Where a point of the first character's face (metres) lands on the canvas, CSS pixels.
state.project = function (x, y, z) {
  const c = state.characters.values().next().value;
  const offset = c && c.group ? c.group.position.x : 0;
  const v = new THREE.Vector3(x + offset, y, z).project(camera);
  return [(v.x + 1) / 2 * canvas.clientWidth, (1 - v.y) / 2 * canvas.clientHeight];
};

// -- viewer connections ---------------------------------------------------------------------

// The server clock, seen from here: performance.now() minus the smallest delay of recent
// frames (arrival minus `t`). A frame that waited in a busy page's queue only adds delay, so
// the minimum is the network's own; the audio is scheduled on this clock.
const CLOCK_WINDOW = 300;  // frames
const delays = [];
function noteFrameArrival(t) {
  delays.push(performance.now() / 1000 - t);
  if (delays.length > CLOCK_WINDOW) delays.shift();
  state.clockDelay = Math.min(...delays);
}
function serverNow() {
  if (state.clockDelay === undefined) return 0;
  return performance.now() / 1000 - state.clockDelay;
}

function onViewerMessage(c, m) {
  if (m.type === "mesh") {
    c.mesh = m; c.model = null; c.lastDecoded = null; c.lastNT = null;
    c.decoder = new FapStreamDecoder(m.fapSteps ? new Uint16Array(m.fapSteps.slice().buffer) : null, m.fapGroups);
    buildMesh(c);
    state.meshLoaded = true; state.fps = m.fps;
  } else if (m.type === "model") {
    c.model = fm.parseModel(m, new Float32Array(c.mesh.neutral.slice().buffer));
    buildMesh(c);
  } else if (m.type === "frame") {
    onFrame(c, m);
  } else if (m.type === "same") {
    onSame(c, m);
  } else if (m.type === "audio") {
    state.audioChunks = (state.audioChunks || 0) + 1;
    if (state.audio) state.audio.push(c.id, m, serverNow());
  } else if (m.type === "audioCut") {
    if (state.audio) state.audio.cut(c.id, m.t);
  } else if (m.type === "scene") {
    onScene(m);
  } else if (m.type === "error") {
    log("warning", `viewer of ${c.id}: ${m.reason}`);
  }
}

function onFrame(c, m) {
  noteFrameArrival(m.t);
  c.lastNT = { n: m.n, t: m.t };
  let faps = null, count = 0;
  if (m.coded) {
    faps = c.decoder.decode(m.n, m.coded, m.codedRef ?? null);  // null until the next intra frame
    if (faps) count = faps.reduce((k, v) => k + (v !== 0 ? 1 : 0), 0);
  } else if (m.fap) {
    faps = new Float64Array(68);
    const ids = m.fap.ids, values = new Float32Array(m.fap.values.slice().buffer);
    for (let i = 0; i < ids.length; i++) faps[ids[i] - 1] = values[i];
    count = ids.length;
  }
  if (m.arkit) {
    c.arkit = decodeArkit(m.arkit);
    if (state.avatar && c === state.characters.values().next().value) {
      state.avatar.apply(c.arkit.weights);
      state.avatar.pose(c.arkit.pose);
    }
  }
  if (faps) {
    applyFaps(c, faps);
    if (state.decoded.length >= 600) state.decoded.shift();
    c.lastDecoded = Array.from(faps);
    state.decoded.push({ character: c.id, n: m.n, faps: c.lastDecoded });
  } else {
    applyDelta(c, m);
  }
  c.frames++;
  state.frames++;
  state.dirty = true;
  state.lastFrame = { n: m.n, t: m.t, faps: count, at: performance.now(), character: c.id };
}

// The server time of frame n, from an earlier frame's n and t (frames are one period apart).
function frameTime(earlier, n) { return earlier.t + (n - earlier.n) / (state.fps || 60); }

// Frame n shows what the last frame showed (protocols/viewer.md): nothing to apply.
function onSame(c, m) {
  c.frames++;
  state.frames++;
  // A same is a tick of the clock too: its time (the last frame's, moved on by the frame
  // period) keeps the estimate of the server's clock fresh. Without it a face at rest
  // gave the estimate only its first frames, often late (the page still loading), and
  // speech was then scheduled that much late (340 ms seen).
  if (c.lastNT) noteFrameArrival(frameTime(c.lastNT, m.n));
  if (c.arkit && state.avatar && c === state.characters.values().next().value) {
    state.avatar.apply(c.arkit.weights);  // the same weights and pose, one frame more
    state.avatar.pose(c.arkit.pose);
  }
  if (c.lastDecoded) {  // frame n decodes to what the last frame decoded to
    if (state.decoded.length >= 600) state.decoded.shift();
    state.decoded.push({ character: c.id, n: m.n, faps: c.lastDecoded });
  }
  const last = state.lastFrame;
  if (last && last.character === c.id) {
    state.lastFrame = { ...last, n: m.n, t: frameTime(last, m.n), at: performance.now() };
  }
}

function watchCharacter(id) {
  if (state.characters.has(id)) return state.characters.get(id);
  const c = { id, view: null, mesh: null, model: null, faps: new Float64Array(68), frames: 0,
              decoder: new FapStreamDecoder() };
  state.characters.set(id, c);
  const options = { character: id, model: true, vertices: "none", scene: true,
                    token: token() || undefined };
  if (state.stream === "coded") { options.coded = true; options.fap = false; }
  if (state.stream === "arkit" || (state.avatarOffered && state.characters.size === 1)) {
    options.arkit = true;
  }
  (async () => {
    let view;
    try {
      view = await ViewClient.connect(wsBase(), options);
      if (!state.characters.has(id) || state.characters.get(id) !== c) { view.close(); return; }
      c.view = view;
      setStatus(`watching ${[...state.characters.keys()].join(", ")}`, true);
      onViewerMessage(c, view.mesh);
      for (;;) onViewerMessage(c, await view.receive());
    } catch (error) {
      if (c.view !== view && view) return;  // closed by us (switching characters)
      if (c.closed) return;
      const words = plainWords(error, "/view");
      setStatus(`viewer of ${id}: ${words}`, false);
      state.errors.push(words);
    }
  })();
  return c;
}

function unwatchAll() {
  for (const c of state.characters.values()) {
    c.closed = true;
    if (c.view) c.view.close();
    if (c.group) scene.remove(c.group);
  }
  state.characters.clear();
  state.framed = false;
  state.dirty = true;
}

// -- submitter: BML and feedback -----------------------------------------------------------

function log(kind, text) {
  state.feedback.push({ kind, text });
  const li = document.createElement("li");
  li.className = kind;
  li.textContent = text;
  $("feedback").appendChild(li);
  $("feedback").scrollTop = $("feedback").scrollHeight;
}

function submitter() {
  if (!state.submitter) {
    state.submitter = (async () => {
      try {
        const client = await SubmitClient.connect(wsBase(), { token: token() || undefined });
        onSubmitterMessage(client.welcome);
        (async () => {
          try {
            for (;;) onSubmitterMessage(await client.receive());
          } catch (error) {
            const words = plainWords(error, "/bml");
            log("warning", `submitter: ${words}`);
            state.errors.push(words);
            state.submitter = null;
          }
        })();
        return client;
      } catch (error) {
        const words = plainWords(error, "/bml");
        log("warning", `submitter: ${words}`);
        state.errors.push(words);
        state.submitter = null;
        return null;
      }
    })();
  }
  return state.submitter;
}

async function send(message) {
  const client = await submitter();
  if (!client) return;
  if (message.type === "bml") client.submit(message.bml, { character: message.character });
  else client.interrupt(message.block, { character: message.character });
}

function currentCharacter() { return $("character").value.trim() || "default"; }

function onSubmitterMessage(m) {
  if (m.type === "welcome") { log("block", `connected: server ${m.server}, protocol ${m.protocol}`); return; }
  if (m.type === "block") {
    log("block", `${m.character}/${m.block}: ${m.state}`);
    const b = state.blocks.get(m.block);
    if (b) b.state = m.state;
    if (m.state === "accepted" && !b) state.blocks.set(m.block, newBlock(m.block, m.character));
    if (m.state === "accepted") state.blocks.get(m.block).state = "running";
    renderRunning();
    return;
  }
  if (m.type === "feedback") {
    log(m.kind === "warning" ? "warning" : "", m.xml);
    onFeedback(m);
  }
}

// -- the timeline ------------------------------------------------------------------------------

// BML 1.0's standard sync points (attributes of a behaviour in predictionFeedback).
const SYNC_NAMES = new Set(["start", "ready", "strokeStart", "stroke", "strokeEnd", "relax",
                            "end", "attackPeak"]);

function newBlock(id, character) {
  return { id, character, start: null, end: null, behaviours: new Map(), state: "pending" };
}

function onFeedback(m) {
  let b = state.blocks.get(m.block);
  if (!b) { b = newBlock(m.block, m.character); state.blocks.set(m.block, b); }
  const doc = new DOMParser().parseFromString(m.xml, "application/xml");
  const root = doc.documentElement;
  if (m.kind === "prediction") {
    for (const child of root.children) {
      if (child.localName === "bml") {
        b.start = parseFloat(child.getAttribute("globalStart"));
        b.end = parseFloat(child.getAttribute("globalEnd"));
        continue;
      }
      let id = child.getAttribute("id") || "";
      if (id.startsWith(`${m.block}:`)) id = id.slice(m.block.length + 1);
      const syncs = b.behaviours.get(id)?.syncs || new Map();
      for (const attr of child.attributes) {
        if (!SYNC_NAMES.has(attr.name)) continue;
        const t = parseFloat(attr.value);
        if (Number.isFinite(t) && !syncs.has(attr.name)) syncs.set(attr.name, { t, fired: null });
        else if (Number.isFinite(t)) syncs.get(attr.name).t = t;
      }
      for (const sync of child.getElementsByTagNameNS("*", "sync")) {
        const t = parseFloat(sync.getAttribute("globalTime"));
        if (Number.isFinite(t)) syncs.set(sync.getAttribute("id"), { t, fired: null });
      }
      b.behaviours.set(id, { type: child.localName, syncs });
    }
  } else if (m.kind === "syncPointProgress") {
    const parts = (root.getAttribute("id") || "").split(":");
    const behaviour = b.behaviours.get(parts[1]);
    const syncName = parts.slice(2).join(":");
    const t = parseFloat(root.getAttribute("globalTime"));
    if (behaviour) {
      const sync = behaviour.syncs.get(syncName) || { t, fired: null };
      sync.fired = t;
      behaviour.syncs.set(syncName, sync);
    }
  }
}

function renderRunning() {
  const box = $("running");
  box.innerHTML = "";
  for (const b of state.blocks.values()) {
    if (b.state !== "running") continue;
    const button = document.createElement("button");
    button.textContent = `interrupt ${b.id}`;
    button.dataset.block = b.id;
    button.onclick = () => send({ type: "interrupt", block: b.id, character: b.character });
    box.appendChild(button);
  }
}

function drawTimeline() {
  const t = $("timeline");
  const g = t.getContext("2d");
  const w = t.width, h = t.height, now = serverNow();
  const before = 3, after = 7, x = (time) => (time - now + before) / (before + after) * w;
  g.fillStyle = "#141517"; g.fillRect(0, 0, w, h);
  g.font = "10px monospace";
  let row = 0;
  const rows = Math.floor(h / 14);
  const blocks = [...state.blocks.values()].filter((b) => b.start !== null).slice(-6);
  for (const b of blocks) {
    for (const [id, behaviour] of b.behaviours) {
      if (row >= rows) break;
      const y = row * 14 + 2;
      const times = [...behaviour.syncs.values()].map((s) => s.t);
      const lo = Math.min(...times), hi = Math.max(...times);
      g.fillStyle = b.state === "interrupted" ? "#5a3a3a" : (b.state === "done" ? "#33404d" : "#3b6ea5");
      g.fillRect(x(lo), y, Math.max(2, x(hi) - x(lo)), 10);
      for (const [name, s] of behaviour.syncs) {
        g.fillStyle = s.fired !== null ? "#ffd24a" : "#9aa";
        g.fillRect(x(s.fired ?? s.t) - 1, y - 1, 2, 12);
        if (s.fired !== null && now - s.fired < 0.6) g.fillText(name, x(s.fired) + 2, y + 9);
      }
      g.fillStyle = "#ddd";
      g.fillText(`${b.id}:${id}`, 2, y + 9);
      row++;
    }
  }
  g.fillStyle = "#f05050"; g.fillRect(x(now), 0, 1, h);
}

// -- examples ----------------------------------------------------------------------------------

async function loadExamples() {
  try {
    const examples = await (await fetch("/static/examples.json")).json();
    for (const example of examples) {
      const button = document.createElement("button");
      button.textContent = example.title;
      button.title = example.file;
      button.onclick = () => {
        $("bml").value = example.bml;
        send({ type: "bml", bml: example.bml, character: currentCharacter() });
      };
      $("examples").appendChild(button);
    }
  } catch (error) { /* examples are a convenience */ }
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

// -- the loop ---------------------------------------------------------------------------------

// Draw only when something changed (a frame, the camera, a mesh): software WebGL on a busy
// machine spends most of its time here otherwise. The timeline redraws at most 10 times a
// second.
let lastTimeline = 0;
function draw(now) {
  requestAnimationFrame(draw);
  if (state.dirty) {
    state.dirty = false;
    renderer.render(scene, camera);
    if (state.lastFrame) {  // when each frame's picture was drawn (audio sync is measured on it)
      state.drawn.push({ t: state.lastFrame.t, at: performance.now() });
      if (state.drawn.length > 600) state.drawn.shift();
    }
  }
  if (now - lastTimeline < 100) return;
  lastTimeline = now;
  drawTimeline();
  const f = state.lastFrame;
  $("frameinfo").textContent = f
    ? `frame ${f.n}  t=${f.t.toFixed(3)} s  ${f.faps} FAPs set  (${state.frames} received, ${state.gpu ? "GPU" : "CPU"} deformation)`
    : "neutral";
}

$("watch").onclick = async () => {
  unwatchAll();
  const old = state.submitter;  // the token may have changed: connect again when needed
  state.submitter = null;
  if (old) { const client = await old; if (client) client.close(); }
  watchCharacter(currentCharacter());
  refreshCharacters();
};
$("add").onclick = () => { watchCharacter(currentCharacter()); refreshCharacters(); };
$("stream").onchange = () => {
  state.stream = $("stream").value;
  const ids = [...state.characters.keys()];
  unwatchAll();
  for (const id of ids) watchCharacter(id);
};
$("send").onclick = () => send({ type: "bml", bml: $("bml").value, character: currentCharacter() });
$("interrupt").onclick = () => send({ type: "interrupt", block: $("interruptId").value.trim(),
                                      character: currentCharacter() });
$("clear").onclick = () => { $("feedback").innerHTML = ""; };
$("sound").onclick = async () => {
  if (!state.audio) state.audio = new AudioPlayer();
  await state.audio.resume();
  $("sound").textContent = "Sound is on";
};

const params = new URLSearchParams(location.search);
if (params.get("token")) $("token").value = params.get("token");
if (params.get("stream")) { state.stream = params.get("stream"); $("stream").value = state.stream; }
const wanted = (params.get("character") || "default").split(",").filter(Boolean);
$("character").value = wanted[0];
// an avatar (realizer serve --avatar) follows the first character's ARKit weights
try {
  state.avatarOffered = params.get("avatar") !== "false" && (await (await fetch("/avatar.json")).json()).avatar;
} catch (error) { state.avatarOffered = false; }
for (const id of wanted) watchCharacter(id);
if (state.avatarOffered) {
  import("/static/avatar.js").then((m) => m.loadAvatar(scene, state, THREE))
    .catch((error) => log("warning", `the avatar could not be loaded: ${error.message}`));
}
loadExamples();
refreshCharacters();
requestAnimationFrame(draw);
state.ready = true;
export { state, ARKIT_NAMES };
