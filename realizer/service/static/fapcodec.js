// Decoders of the viewer's coded streams (protocols/viewer.md): MPEG-4 low-delay FAP coding
// ("Face and 2-D mesh animation in MPEG-4", section 2.2.1; the encoder is
// realizer/face/fapcoding.py, this is its bit-exact port) and ARKit weights.
// The FAP step sizes (Table 7) and groups (Table 2) come in the mesh message.

const RESIDUAL_RANGE = 15, ESCAPE = 2 * RESIDUAL_RANGE + 1, ESCAPE_BITS = 17;
const INCREMENT = 24, MAX_TOTAL = 1 << 13, MAX_FRAME_BYTES = 4096;
const TOP = 4294967295, HALF = 2147483648, QUARTER = 1073741824;
const MASK_NONE = 0, MASK_SOME = 1, MASK_ALL = 3;

class Decoder {
  constructor(bytes) {
    this.data = bytes; this.at = 0; this.low = 0; this.high = TOP; this.value = 0;
    for (let i = 0; i < 32; i++) this.value = 2 * this.value + this.bit();
  }
  bit() {
    const i = this.at++;
    if ((i >> 3) >= this.data.length) {
      if (i > 8 * this.data.length + 64) throw new Error("coded FAP frame ends too early");
      return 0;
    }
    return (this.data[i >> 3] >> (7 - (i & 7))) & 1;
  }
  target(total) {
    const span = this.high - this.low + 1;
    return Math.floor(((this.value - this.low + 1) * total - 1) / span);
  }
  consume(lo, hi, total) {
    const span = this.high - this.low + 1;
    this.high = this.low + Math.floor(span * hi / total) - 1;
    this.low = this.low + Math.floor(span * lo / total);
    for (;;) {
      if (this.high < HALF) { /* nothing to subtract */ }
      else if (this.low >= HALF) { this.value -= HALF; this.low -= HALF; this.high -= HALF; }
      else if (this.low >= QUARTER && this.high < 3 * QUARTER) {
        this.value -= QUARTER; this.low -= QUARTER; this.high -= QUARTER;
      } else break;
      this.low = 2 * this.low; this.high = 2 * this.high + 1;
      this.value = 2 * this.value + this.bit();
    }
  }
}

class Model {
  constructor(size) { this.counts = new Array(size).fill(1); this.total = size; }
  decode(coder) {
    const target = coder.target(this.total);
    let low = 0;
    for (let s = 0; s < this.counts.length; s++) {
      const c = this.counts[s];
      if (target < low + c) {
        coder.consume(low, low + c, this.total);
        this.counts[s] += INCREMENT; this.total += INCREMENT;
        if (this.total > MAX_TOTAL) {
          this.counts = this.counts.map((x) => (x + 1) >> 1);
          this.total = this.counts.reduce((a, b) => a + b, 0);
        }
        return s;
      }
      low += c;
    }
    throw new Error("corrupt coded FAP frame");
  }
}

function bits(coder, count) {
  let v = 0;
  for (let i = 0; i < count; i++) {
    const b = coder.target(2) >= 1 ? 1 : 0;
    coder.consume(b, b + 1, 2);
    v = 2 * v + b;
  }
  return v;
}

function freshModels() {
  const make = (n, size) => Array.from({ length: n }, () => new Model(size));
  return { residual: make(68, ESCAPE + 1), bit: make(68, 2), kind: make(10, 4) };
}

// Decodes one character's coded FAP frames in order. `steps` (68 Table 7 QP) and `groups`
// (68 group numbers) from the mesh message (fapSteps, fapGroups).
export class FapStreamDecoder {
  constructor(steps = null, groups = null) {
    this.setTables(steps, groups);
    this.previous = new Float64Array(68); this.models = freshModels();
    this.synced = false; this.number = null;
  }
  setTables(steps, groups) {
    this.steps = steps;
    this.groups = [];
    if (!groups) return;
    const byGroup = new Map();
    for (let i = 0; i < 68; i++) {
      if (!byGroup.has(groups[i])) byGroup.set(groups[i], []);
      byGroup.get(groups[i]).push(i);
    }
    this.groups = [...byGroup.keys()].sort((a, b) => a - b).map((g) => byGroup.get(g));
  }
  // A (68,) Float64Array of FAP values (unset FAPs 0) and sets this.mask; or null for an
  // inter frame this decoder cannot decode yet (joined mid-stream, or a missed frame).
  decode(number, frame, ref = null) {
    if (!this.steps) throw new Error("no FAP step table (the mesh message has none)");
    if (!frame.length || frame.length > MAX_FRAME_BYTES) throw new Error("bad coded FAP frame size");
    const intra = (frame[0] & 0x80) !== 0;
    const follows = ref === null || ref === undefined || ref === this.number;
    if (intra) { this.models = freshModels(); this.previous = new Float64Array(68); this.synced = true; }
    else if (!(this.synced && follows)) { this.synced = false; return null; }
    this.number = number;
    const quant = frame[0] & 0x1f;
    const coder = new Decoder(frame.subarray(1));
    const values = new Float64Array(68), mask = new Uint8Array(68);
    const m = this.models;
    try {
      this.groups.forEach((group, g) => {
        const kind = m.kind[g].decode(coder);
        if (kind === MASK_NONE) return;
        let present;
        if (kind === MASK_ALL) present = group;
        else if (kind === MASK_SOME) present = group.filter((i) => m.bit[i].decode(coder) === 1);
        else throw new Error("reserved FAP mask type 2");
        for (const i of present) {
          const symbol = m.residual[i].decode(coder);
          let e;
          if (symbol === ESCAPE) {
            const negative = bits(coder, 1);
            e = bits(coder, ESCAPE_BITS);
            if (negative) e = -e;
          } else e = symbol - RESIDUAL_RANGE;
          values[i] = this.previous[i] + e * this.steps[i] * quant;
          mask[i] = 1;
        }
      });
    } catch (error) { this.synced = false; throw error; }
    this.previous = values.slice();
    this.mask = mask;
    return values;
  }
}

// The ARKit payload of a frame: 52 uint8 weights (0..255 for 0..1) in ARKIT_NAMES order, then
// 7 int16 LE angles in 1e-4 rad (head pitch, yaw, roll; left eye pitch, yaw; right eye pitch,
// yaw). Returns {weights: Float32Array(52), pose: Float32Array(7)}.
export function decodeArkit(bytes) {
  const weights = new Float32Array(52);
  for (let i = 0; i < 52; i++) weights[i] = bytes[i] / 255;
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const pose = new Float32Array(7);
  for (let k = 0; k < 7 && 52 + 2 * k + 1 < bytes.length; k++) pose[k] = view.getInt16(52 + 2 * k, true) * 1e-4;
  return { weights, pose };
}

// Apple's 52 blendshape names, in the order of the arkit payload (protocols/viewer.md).
export const ARKIT_NAMES = [
  "eyeBlinkLeft", "eyeLookDownLeft", "eyeLookInLeft", "eyeLookOutLeft", "eyeLookUpLeft",
  "eyeSquintLeft", "eyeWideLeft", "eyeBlinkRight", "eyeLookDownRight", "eyeLookInRight",
  "eyeLookOutRight", "eyeLookUpRight", "eyeSquintRight", "eyeWideRight", "jawForward",
  "jawLeft", "jawRight", "jawOpen", "mouthClose", "mouthFunnel", "mouthPucker", "mouthLeft",
  "mouthRight", "mouthSmileLeft", "mouthSmileRight", "mouthFrownLeft", "mouthFrownRight",
  "mouthDimpleLeft", "mouthDimpleRight", "mouthStretchLeft", "mouthStretchRight",
  "mouthRollLower", "mouthRollUpper", "mouthShrugLower", "mouthShrugUpper", "mouthPressLeft",
  "mouthPressRight", "mouthLowerDownLeft", "mouthLowerDownRight", "mouthUpperUpLeft",
  "mouthUpperUpRight", "browDownLeft", "browDownRight", "browInnerUp", "browOuterUpLeft",
  "browOuterUpRight", "cheekPuff", "cheekSquintLeft", "cheekSquintRight", "noseSneerLeft",
  "noseSneerRight", "tongueOut",
];
