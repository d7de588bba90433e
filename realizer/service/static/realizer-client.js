// The realizer service's JavaScript client: an ES module for browsers and Node
// (protocols/submitter.md, protocols/viewer.md). No dependencies.
//
//   import { SubmitClient, ViewClient } from "/static/realizer-client.js";
//   const client = await SubmitClient.connect("ws://127.0.0.1:8765", { character: "Alice" });
//   const state = await client.runBlock(bml, { onEvent: (e) => console.log(e) });
//
// Node 22 and later have a global WebSocket (Node 20: --experimental-websocket);
// elsewhere pass one: `{ WebSocket: (await import("ws")).default }`.
//
// Events: { type: "feedback", character, kind, blockId, time, xml, feedback } where
// `feedback` is the element read: { element, id, blockId, behaviourId, sync,
// time, globalTime, warningType, text, status, characterId } (the fields the
// element has); and { type: "block", character, blockId, state, time, final }.
//
// Errors (all `instanceof ClientError`): ServerUnavailable, Unauthorized (401),
// Forbidden (403), HandshakeRefused (other statuses), ServerBusy (close 1013),
// ConnectionLost (`code`, `reason`; 1001 = the server is stopping), ProtocolError.

export const PROTOCOL_VERSION = 1;
const FINAL_STATES = new Set(["rejected", "done", "interrupted", "failed"]);
const OPEN_TIMEOUT_MS = 10000;

// -- errors ------------------------------------------------------------------------------

export class ClientError extends Error {
  constructor(message) { super(message); this.name = new.target.name; }
}
export class ServerUnavailable extends ClientError {}
export class HandshakeRefused extends ClientError {
  constructor(status, reason) {
    super(`the server refused the connection: ${status} ${reason}`.trim());
    this.status = status;
    this.reason = reason;
  }
}
export class Unauthorized extends HandshakeRefused {}
export class Forbidden extends HandshakeRefused {}
export class ProtocolError extends ClientError {}
export class ConnectionLost extends ClientError {
  constructor(code, reason) {
    super(`the connection closed: ${code ?? "no close frame"} ${reason || ""}`.trim());
    this.code = code;
    this.reason = reason || "";
  }
}
export class ServerBusy extends ConnectionLost {}

function lost(code, reason) {
  return code === 1013 ? new ServerBusy(code, reason) : new ConnectionLost(code, reason);
}

// -- URLs --------------------------------------------------------------------------------

export function endpointUrl(base, path, params) {
  let url = String(base).replace(/\/+$/, "");
  if (url.startsWith("http://")) url = "ws://" + url.slice(7);
  else if (url.startsWith("https://")) url = "wss://" + url.slice(8);
  const query = new URLSearchParams();
  for (const [key, value] of Object.entries(params)) {
    if (value !== undefined && value !== null) query.set(key, String(value));
  }
  const text = query.toString();
  return text ? `${url}${path}?${text}` : `${url}${path}`;
}

// Why a handshake failed: browsers hide the HTTP status of a refused WebSocket
// handshake, so ask the same URL over plain HTTP, where the server answers the
// authorisation check with 401 or 403 before anything else.
async function whyRefused(wsUrl) {
  const httpUrl = wsUrl.replace(/^ws/, "http");
  let reply;
  try {
    reply = await fetch(httpUrl, { method: "GET", cache: "no-store" });
  } catch (error) {
    return new ServerUnavailable(`cannot connect to ${wsUrl}`);
  }
  const body = (await reply.text().catch(() => "")).trim();
  if (reply.status === 401) return new Unauthorized(401, body || "Unauthorized");
  if (reply.status === 403) return new Forbidden(403, body || "Forbidden");
  if (reply.status >= 400 && reply.status !== 426) return new HandshakeRefused(reply.status, body);
  return new ServerUnavailable(`the WebSocket handshake with ${wsUrl} failed`);
}

// -- one connection as a queue of messages --------------------------------------------------

class Connection {
  constructor(socket) {
    this.socket = socket;
    this.queue = [];
    this.waiting = [];
    this.closed = null;
    socket.addEventListener("message", (event) => this.push({ data: event.data }));
    socket.addEventListener("close", (event) => {
      this.closed = lost(event.code === 1006 ? null : event.code, event.reason);
      for (const waiter of this.waiting.splice(0)) waiter.reject(this.closed);
    });
  }
  push(item) {
    const waiter = this.waiting.shift();
    if (waiter) waiter.resolve(item.data);
    else this.queue.push(item);
  }
  // The next message's data; rejects with ConnectionLost when the socket closed,
  // or with an Error named "TimeoutError" after timeoutMs.
  next(timeoutMs) {
    if (this.queue.length) return Promise.resolve(this.queue.shift().data);
    if (this.closed) return Promise.reject(this.closed);
    return new Promise((resolve, reject) => {
      const waiter = { resolve, reject };
      this.waiting.push(waiter);
      if (timeoutMs !== undefined && timeoutMs !== null) {
        const timer = setTimeout(() => {
          const at = this.waiting.indexOf(waiter);
          if (at >= 0) this.waiting.splice(at, 1);
          const error = new Error(`no message for ${timeoutMs} ms`);
          error.name = "TimeoutError";
          reject(error);
        }, timeoutMs);
        waiter.resolve = (value) => { clearTimeout(timer); resolve(value); };
        waiter.reject = (error) => { clearTimeout(timer); reject(error); };
      }
    });
  }
  send(text) {
    if (this.closed) throw this.closed;
    this.socket.send(text);
  }
  close(code = 1000) {
    if (!this.closed) this.socket.close(code);
  }
}

function openSocket(url, WebSocketImpl, binary) {
  const Impl = WebSocketImpl ?? globalThis.WebSocket;
  if (!Impl) {
    throw new ClientError("no WebSocket here: pass { WebSocket } (e.g. the ws package's)");
  }
  return new Promise((resolve, reject) => {
    let socket;
    try {
      socket = new Impl(url);
    } catch (error) {
      reject(new ServerUnavailable(`not a WebSocket URL: ${url}`));
      return;
    }
    if (binary) socket.binaryType = "arraybuffer";
    let opened = false;
    const connection = new Connection(socket);
    const timer = setTimeout(() => {
      if (!opened) { socket.close(); reject(new ServerUnavailable(`no answer from ${url}`)); }
    }, OPEN_TIMEOUT_MS);
    socket.addEventListener("open", () => { opened = true; clearTimeout(timer); resolve(connection); });
    socket.addEventListener("error", () => {
      if (opened) return;
      clearTimeout(timer);
      whyRefused(url).then(reject, reject);
    });
  });
}

// -- feedback ---------------------------------------------------------------------------

const ENTITIES = { amp: "&", lt: "<", gt: ">", quot: '"', apos: "'" };
function unescapeXml(text) {
  let out = "";
  for (let at = 0; at < text.length; at++) {
    const c = text[at];
    const end = c === "&" ? text.indexOf(";", at) : -1;
    if (end > at && end - at <= 8) {
      const name = text.slice(at + 1, end);
      let value = ENTITIES[name];
      if (value === undefined && name[0] === "#") {
        const code = name[1] === "x" ? parseInt(name.slice(2), 16) : parseInt(name.slice(1), 10);
        if (Number.isFinite(code)) value = String.fromCodePoint(code);
      }
      if (value !== undefined) { out += value; at = end; continue; }
    }
    out += c;
  }
  return out;
}

// The root element of one feedback XML text: its local name, attributes and text.
// One left-to-right scan (no regular expression), linear in the text's length.
export function readRootElement(xml) {
  let at = 0;
  for (;;) {
    at = xml.indexOf("<", at);
    if (at < 0) throw new ProtocolError("feedback without an element");
    const next = xml[at + 1];
    if (next !== "?" && next !== "!") break;
    const end = xml.indexOf(next === "?" ? "?>" : ">", at + 2);
    if (end < 0) throw new ProtocolError("unterminated markup in feedback");
    at = end + 1;
  }
  let i = at + 1;
  const isSpace = (c) => c === " " || c === "\n" || c === "\t" || c === "\r";
  while (i < xml.length && !isSpace(xml[i]) && xml[i] !== ">" && xml[i] !== "/") i++;
  const qname = xml.slice(at + 1, i);
  const attributes = {};
  for (;;) {
    while (i < xml.length && isSpace(xml[i])) i++;
    if (i >= xml.length) throw new ProtocolError("unterminated start tag in feedback");
    if (xml[i] === ">" || xml[i] === "/") break;
    const eq = xml.indexOf("=", i);
    if (eq < 0) throw new ProtocolError("attribute without a value in feedback");
    const name = xml.slice(i, eq).trim();
    const quote = xml[eq + 1];
    if (quote !== '"' && quote !== "'") throw new ProtocolError("unquoted attribute in feedback");
    const close = xml.indexOf(quote, eq + 2);
    if (close < 0) throw new ProtocolError("unterminated attribute in feedback");
    attributes[name.slice(name.indexOf(":") + 1)] = unescapeXml(xml.slice(eq + 2, close));
    i = close + 1;
  }
  let text = "";
  if (xml[i] === ">") {
    const end = xml.lastIndexOf("</");
    if (end > i) text = unescapeXml(xml.slice(i + 1, end)).trim();
  }
  return { element: qname.slice(qname.indexOf(":") + 1), attributes, text };
}

// A feedback element as an object (see the top of this file).
export function parseFeedback(xml) {
  const { element, attributes, text } = readRootElement(xml);
  const out = { element, id: attributes.id };
  const number = (name) => {
    if (attributes[name] === undefined) return undefined;
    const value = Number(attributes[name]);
    if (!Number.isFinite(value)) throw new ProtocolError(`${name} is not a number in feedback`);
    return value;
  };
  if (attributes.characterId !== undefined) out.characterId = attributes.characterId;
  if (element === "blockProgress") {
    const [blockId, sync] = String(attributes.id ?? "").split(":");
    Object.assign(out, { blockId, sync, globalTime: number("globalTime") });
    // BMLA's block status (bmla:status: IN_EXEC, DONE, INTERRUPTED, REVOKED)
    const status = attributes["bmla:status"] ?? attributes.status;
    if (status !== undefined) out.status = status;
  } else if (element === "syncPointProgress") {
    const [blockId, behaviourId, sync] = String(attributes.id ?? "").split(":");
    Object.assign(out, {
      blockId, behaviourId, sync, time: number("time"), globalTime: number("globalTime"),
    });
  } else if (element === "warningFeedback") {
    Object.assign(out, { blockId: String(attributes.id ?? "").split(":")[0],
      warningType: attributes.type, text });
  } else if (element !== "predictionFeedback") {
    throw new ProtocolError(`not a BML feedback element: <${element}>`);
  }
  return out;
}

export function eventFrom(message) {
  if (message === null || typeof message !== "object") {
    throw new ProtocolError("the server sent a message that is not a JSON object");
  }
  if (message.type === "feedback") {
    return {
      type: "feedback", character: message.character, kind: message.kind,
      blockId: message.block, time: message.time, xml: message.xml,
      feedback: parseFeedback(String(message.xml)),
    };
  }
  if (message.type === "block") {
    return {
      type: "block", character: message.character, blockId: message.block,
      state: message.state, time: message.time, final: FINAL_STATES.has(message.state),
    };
  }
  throw new ProtocolError(`unexpected message type ${JSON.stringify(message.type)}`);
}

// -- the submitter endpoint ---------------------------------------------------------------

export class SubmitClient {
  // Connect to /bml in JSON mode and read the welcome message.
  static async connect(url, { character, token, WebSocket } = {}) {
    const wsUrl = endpointUrl(url, "/bml", { format: "json", character, token });
    const connection = await openSocket(wsUrl, WebSocket, false);
    const client = new SubmitClient(connection);
    client.welcome = await client.receive(OPEN_TIMEOUT_MS);
    if (client.welcome.type !== "welcome") {
      connection.close();
      throw new ProtocolError(`expected a welcome message, got ${client.welcome.type}`);
    }
    return client;
  }
  constructor(connection) { this.connection = connection; this.welcome = null; }

  submit(bml, { character } = {}) {
    const message = { type: "bml", bml };
    if (character !== undefined) message.character = character;
    this.connection.send(JSON.stringify(message));
  }
  interrupt(blockId, { character } = {}) {
    const message = { type: "interrupt", block: blockId };
    if (character !== undefined) message.character = character;
    this.connection.send(JSON.stringify(message));
  }
  // Add or move the scene target `name` to [x, y, z] metres (protocols/scene.md).
  target(name, position) {
    this.connection.send(JSON.stringify({ type: "target", name, position: Array.from(position, Number) }));
  }
  // The next message as its JSON object.
  async receive(timeoutMs) {
    const data = await this.connection.next(timeoutMs);
    if (typeof data !== "string") throw new ProtocolError("binary data on the submitter endpoint");
    try { return JSON.parse(data); } catch (error) { throw new ProtocolError("text that is not JSON"); }
  }
  // The next message as an event.
  async nextEvent(timeoutMs) { return eventFrom(await this.receive(timeoutMs)); }
  // for await (const event of client.events()) ...
  async *events(timeoutMs) { for (;;) yield await this.nextEvent(timeoutMs); }

  // Submit and read until the block ends; resolves to its final state.
  async runBlock(bml, { blockId, character, onEvent, timeoutMs } = {}) {
    this.submit(bml, { character });
    let id = blockId;
    for (;;) {
      const message = await this.receive(timeoutMs);
      if (id === undefined && message.type === "block") id = message.block;
      if (id !== undefined && message.block !== id && message.block !== "") continue;
      if (onEvent) await onEvent(eventFrom(message));
      if (message.type === "block" && FINAL_STATES.has(message.state)) return message.state;
    }
  }
  close() { this.connection.close(); }
}

// -- the viewer endpoint ------------------------------------------------------------------

export class ViewClient {
  // Connect to /view and read the mesh. same (default true): a tick that shows what
  // the last frame showed comes as a few-byte `same` message (frames() repeats the
  // last frame for it; receive() gives it as it is).
  static async connect(url, { character, fap = true, vertices = "none", model, coded, arkit,
    scene, same = true, token, WebSocket } = {}) {
    const params = { character, fap: fap ? "true" : "false", vertices, token,
                     same: same ? "true" : "false" };
    if (model !== undefined) params.model = model ? "true" : "false";
    if (scene !== undefined) params.scene = scene ? "true" : "false";
    if (coded !== undefined) params.coded = coded ? "true" : "false";
    if (arkit !== undefined) params.arkit = arkit ? "true" : "false";
    const connection = await openSocket(endpointUrl(url, "/view", params), WebSocket, true);
    const client = new ViewClient(connection);
    const first = await client.receive(OPEN_TIMEOUT_MS);
    if (first.type !== "mesh") {
      connection.close();
      throw new ProtocolError(`expected the mesh first, got ${first.type}`);
    }
    return client;
  }
  constructor(connection) {
    this.connection = connection; this.mesh = null; this.model = null; this.lastFrame = null;
  }

  async receive(timeoutMs) {
    const data = await this.connection.next(timeoutMs);
    if (typeof data === "string") throw new ProtocolError("text on the viewer endpoint");
    const message = decodeMsgpack(data instanceof ArrayBuffer ? data : toArrayBuffer(data));
    if (message === null || typeof message !== "object" || !message.type) {
      throw new ProtocolError("a viewer message without a type");
    }
    if (message.type === "mesh") { this.mesh = message; this.lastFrame = null; }
    if (message.type === "model") this.model = message;
    if (message.type === "frame") this.lastFrame = message;  // what a `same` repeats
    return message;
  }
  // for await (const frame of view.frames(60)) ... One per tick: a `same` message
  // is given as the last frame with its n and t moved on and same: true.
  async *frames(count, timeoutMs) {
    for (let seen = 0; count === undefined || seen < count;) {
      const message = await this.receive(timeoutMs);
      const last = this.lastFrame;  // null after a mesh: a new subscription's first comes whole
      if (message.type === "frame") { seen++; yield message; }
      else if (message.type === "same" && last) {
        const t = last.t + (message.n - last.n) / (this.mesh.fps || 1);
        seen++;
        yield { ...last, n: message.n, t, same: true };
      }
    }
  }
  subscribe(changes) { this.connection.send(JSON.stringify({ type: "subscribe", ...changes })); }

  // Map of FAP number -> value (FAPU-scaled) of the FAPs a frame sets.
  static faps(frame) {
    const out = new Map();
    if (!frame.fap) return out;
    const ids = frame.fap.ids;
    const values = littleEndian(frame.fap.values);
    for (let i = 0; i < ids.length; i++) out.set(ids[i], values.getFloat32(4 * i, true));
    return out;
  }
  // The frame's vertex positions, metres, as a Float32Array of n x 3 (the neutral
  // pose where the frame carries none).
  vertices(frame) {
    const n = this.mesh.vertexCount;
    const neutral = littleEndian(this.mesh.neutral);
    const out = new Float32Array(3 * n);
    if (frame.vertices) {
      const v = littleEndian(frame.vertices);
      for (let i = 0; i < 3 * n; i++) out[i] = v.getFloat32(4 * i, true);
      return out;
    }
    for (let i = 0; i < 3 * n; i++) out[i] = neutral.getFloat32(4 * i, true);
    if (frame.delta) {
      const ids = littleEndian(frame.delta.ids);
      const q = littleEndian(frame.delta.q);
      const step = this.mesh.step;
      for (let k = 0; k < frame.delta.ids.length / 4; k++) {
        const vertex = ids.getUint32(4 * k, true);
        for (let axis = 0; axis < 3; axis++) {
          out[3 * vertex + axis] += step * q.getInt16(2 * (3 * k + axis), true);
        }
      }
    }
    return out;
  }
  close() { this.connection.close(); }
}

function littleEndian(bytes) { return new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength); }
function toArrayBuffer(data) {
  // Node's ws hands out Buffers (Uint8Array views); browsers ArrayBuffers.
  if (ArrayBuffer.isView(data)) return data.buffer.slice(data.byteOffset, data.byteOffset + data.byteLength);
  throw new ProtocolError("a viewer message that is not binary");
}

// -- msgpack (what the viewer endpoint sends: maps, arrays, str, bin, numbers, nil, bool) ---

export function decodeMsgpack(buffer) {
  const bytes = new Uint8Array(buffer);
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const text = new TextDecoder();
  let at = 0;
  const need = (n) => { if (at + n > bytes.length) throw new ProtocolError("truncated msgpack"); };
  const str = (n) => { need(n); const s = text.decode(bytes.subarray(at, at + n)); at += n; return s; };
  const bin = (n) => { need(n); const b = bytes.subarray(at, at + n); at += n; return b; };
  const arr = (n) => { need(n); const a = new Array(n); for (let i = 0; i < n; i++) a[i] = read(); return a; };
  const map = (n) => { need(n); const m = {}; for (let i = 0; i < n; i++) { const k = read(); m[k] = read(); } return m; };
  const u = (size) => {
    need(size);
    const v = size === 1 ? view.getUint8(at) : size === 2 ? view.getUint16(at)
      : size === 4 ? view.getUint32(at) : Number(view.getBigUint64(at));
    at += size;
    return v;
  };
  const s = (size) => {
    need(size);
    const v = size === 1 ? view.getInt8(at) : size === 2 ? view.getInt16(at)
      : size === 4 ? view.getInt32(at) : Number(view.getBigInt64(at));
    at += size;
    return v;
  };
  function read() {
    need(1);
    const t = bytes[at++];
    if (t <= 0x7f) return t;
    if (t <= 0x8f) return map(t & 0x0f);
    if (t <= 0x9f) return arr(t & 0x0f);
    if (t <= 0xbf) return str(t & 0x1f);
    if (t >= 0xe0) return t - 0x100;
    switch (t) {
      case 0xc0: return null;
      case 0xc2: return false;
      case 0xc3: return true;
      case 0xc4: return bin(u(1));
      case 0xc5: return bin(u(2));
      case 0xc6: return bin(u(4));
      case 0xca: { need(4); const v = view.getFloat32(at); at += 4; return v; }
      case 0xcb: { need(8); const v = view.getFloat64(at); at += 8; return v; }
      case 0xcc: return u(1);
      case 0xcd: return u(2);
      case 0xce: return u(4);
      case 0xcf: return u(8);
      case 0xd0: return s(1);
      case 0xd1: return s(2);
      case 0xd2: return s(4);
      case 0xd3: return s(8);
      case 0xd9: return str(u(1));
      case 0xda: return str(u(2));
      case 0xdb: return str(u(4));
      case 0xdc: return arr(u(2));
      case 0xdd: return arr(u(4));
      case 0xde: return map(u(2));
      case 0xdf: return map(u(4));
      default: throw new ProtocolError(`unsupported msgpack type 0x${t.toString(16)}`);
    }
  }
  return read();
}
