// The face's deformation model, evaluated in the browser: the `model` message of
// protocols/viewer.md (the arrays of realizer.face.gpu_model, the same data the server's
// numpy deform() evaluates), turned into GPU textures and a GLSL function, plus a plain
// JavaScript evaluator for browsers without WebGL2 and for tests.
//
// Per frame (see realizer/face/gpu_model.py): column amounts from the FAPs, then per vertex
// capped influence sums plus linear FaceDefMesh terms, then the rigid groups in order, then
// the pose. MPEG-4 ("Face and 2-D mesh animation in MPEG-4", section 2.1.3): the decoder owns
// the face model, the stream carries only parameters.

export const MODEL_LAYOUT = 1;
export const TEXTURE_WIDTH = 2048;  // WebGL2 guarantees at least 2048 texels per row

function f64(bytes) { return new Float64Array(bytes.slice().buffer); }
function f32(bytes) { return new Float32Array(bytes.slice().buffer); }
function u32(bytes) { return new Uint32Array(bytes.slice().buffer); }

// The model message -> typed arrays. Throws for a layout this viewer does not know.
export function parseModel(message, neutral) {
  if (message.layout !== MODEL_LAYOUT) throw new Error(`unknown model layout ${message.layout}`);
  const model = {
    vertexCount: neutral.length / 3,
    neutral,
    columnCount: message.columnCount,
    groupCount: message.groupCount,
    columnFap: Uint8Array.from(message.columnFap),
    columnUnit: f64(message.columnUnit),
    columnLow: f64(message.columnLow),
    columnHigh: f64(message.columnHigh),
    columnZero: f64(message.columnZero),
    entries: f32(message.entries),   // (e, 4) code, column, coef, mag
    ranges: u32(message.ranges),     // (n, 4) entry start, count, link start, count
    links: f32(message.links),       // (l, 2) group, weight
    members: f64(message.members),   // (k, 10) group, kind, fap, unit, axis, pivot
    unidirectional: Uint8Array.from(message.unidirectional),
  };
  return model;
}

// A (68,) Float64Array of FAP values (FAP n at n-1) as the deformer sees them.
export function prepared(model, faps) {
  const v = Float64Array.from(faps);
  for (const number of model.unidirectional) v[number - 1] = Math.max(v[number - 1], 0);
  v[0] = 0; v[1] = 0;
  return v;
}

export function amounts(model, values) {
  const out = new Float64Array(model.columnCount);
  for (let j = 0; j < model.columnCount; j++) {
    const v = values[model.columnFap[j]];
    const clipped = Math.min(Math.max(v, model.columnLow[j]), model.columnHigh[j]);
    out[j] = (clipped - model.columnZero[j]) * model.columnUnit[j];
  }
  return out;
}

function rotation(x, y, z, angle) {
  const c = Math.cos(angle), s = Math.sin(angle), t = 1 - c;
  return [c + t * x * x, t * x * y - s * z, t * x * z + s * y,
          t * x * y + s * z, c + t * y * y, t * y * z - s * x,
          t * x * z - s * y, t * y * z + s * x, c + t * z * z];
}

// Row-major 3x4 maps [r00 r01 r02 t0 r10 ... t2] of the groups (groupCount of them) and,
// last, the pose: groupCount + 1 maps in one Float64Array.
export function groupMaps(model, values) {
  const g = model.groupCount;
  const maps = new Float64Array((g + 1) * 12);
  for (let i = 0; i <= g; i++) { maps[i * 12] = 1; maps[i * 12 + 5] = 1; maps[i * 12 + 10] = 1; }
  const m = model.members;
  for (let r = 0; r < m.length / 10; r++) {
    const group = m[r * 10], kind = m[r * 10 + 1], fap = m[r * 10 + 2], unit = m[r * 10 + 3];
    const amount = values[fap] * unit;
    if (amount === 0) continue;
    const at = (group < 0 ? g : group) * 12;
    const ax = m[r * 10 + 4], ay = m[r * 10 + 5], az = m[r * 10 + 6];
    if (kind === 0) {
      maps[at + 3] += amount * ax; maps[at + 7] += amount * ay; maps[at + 11] += amount * az;
      continue;
    }
    const rot = rotation(ax, ay, az, amount);
    const px = m[r * 10 + 7], py = m[r * 10 + 8], pz = m[r * 10 + 9];
    const old = maps.slice(at, at + 12);
    for (let row = 0; row < 3; row++) {
      for (let col = 0; col < 4; col++) {
        let sum = 0;
        for (let k = 0; k < 3; k++) sum += rot[row * 3 + k] * old[k * 4 + col];
        maps[at + row * 4 + col] = sum;
      }
    }
    // x -> rot (x - pivot) + pivot after the motion so far
    const pv = [px, py, pz];
    for (let row = 0; row < 3; row++) {
      let turned = 0;
      for (let k = 0; k < 3; k++) turned += rot[row * 3 + k] * pv[k];
      maps[at + row * 4 + 3] += pv[row] - turned;
    }
  }
  return maps;
}

// (n * 3) Float32Array of deformed vertices: the JavaScript evaluator of the model.
export function deformCPU(model, faps) {
  const values = prepared(model, faps);
  const a = amounts(model, values);
  const maps = groupMaps(model, values);
  const n = model.vertexCount, e = model.entries, rg = model.ranges, lk = model.links;
  const out = new Float32Array(n * 3);
  const pos = new Float64Array(3), posPeak = new Float64Array(3);
  const neg = new Float64Array(3), negPeak = new Float64Array(3), lin = new Float64Array(3);
  const p = new Float64Array(3);
  const pose = model.groupCount * 12;
  for (let i = 0; i < n; i++) {
    pos.fill(0); posPeak.fill(0); neg.fill(0); negPeak.fill(0); lin.fill(0);
    const start = rg[i * 4], count = rg[i * 4 + 1];
    for (let k = start; k < start + count; k++) {
      const code = e[k * 4], amount = a[e[k * 4 + 1]];
      const axis = code % 3;
      const push = e[k * 4 + 2] * amount;
      if (code >= 3) { lin[axis] += push; continue; }
      const peak = e[k * 4 + 3] * Math.abs(amount);
      if (push < 0) { neg[axis] -= push; negPeak[axis] = Math.max(negPeak[axis], peak); }
      else { pos[axis] += push; posPeak[axis] = Math.max(posPeak[axis], peak); }
    }
    for (let c = 0; c < 3; c++) {
      p[c] = model.neutral[i * 3 + c] + Math.min(pos[c], posPeak[c]) - Math.min(neg[c], negPeak[c]) + lin[c];
    }
    const ls = rg[i * 4 + 2], lc = rg[i * 4 + 3];
    for (let k = ls; k < ls + lc; k++) {
      const at = lk[k * 2] * 12, w = lk[k * 2 + 1];
      const x = p[0], y = p[1], z = p[2];
      for (let c = 0; c < 3; c++) {
        const moved = maps[at + c * 4] * x + maps[at + c * 4 + 1] * y + maps[at + c * 4 + 2] * z + maps[at + c * 4 + 3];
        p[c] += w * (moved - p[c]);
      }
    }
    const x = p[0], y = p[1], z = p[2];
    for (let c = 0; c < 3; c++) {
      out[i * 3 + c] = maps[pose + c * 4] * x + maps[pose + c * 4 + 1] * y + maps[pose + c * 4 + 2] * z + maps[pose + c * 4 + 3];
    }
  }
  return out;
}

// -- the GPU path --------------------------------------------------------------------------

// GLSL ES 3.00 declarations and the function rzDeform(neutral) -> deformed position.
// Attribute rzRange: (entry start, count, link start, count) per vertex.
export const GLSL_DEFORM = `
uniform highp sampler2D rzEntries;  // RGBA32F: code, column, coef, mag
uniform highp sampler2D rzLinks;    // RGBA32F: group, weight, 0, 0
uniform highp sampler2D rzAmounts;  // RGBA32F: amount (metres) in .r
uniform highp sampler2D rzMaps;     // RGBA32F: 3 texels (rows) per group map, pose last
uniform int rzGroupCount;
in vec4 rzRange;
ivec2 rzAt(int i) { return ivec2(i % ${TEXTURE_WIDTH}, i / ${TEXTURE_WIDTH}); }
vec3 rzApply(int g, vec3 p) {
  vec4 r0 = texelFetch(rzMaps, ivec2(3 * g, 0), 0);
  vec4 r1 = texelFetch(rzMaps, ivec2(3 * g + 1, 0), 0);
  vec4 r2 = texelFetch(rzMaps, ivec2(3 * g + 2, 0), 0);
  vec4 q = vec4(p, 1.0);
  return vec3(dot(r0, q), dot(r1, q), dot(r2, q));
}
vec3 rzDeform(vec3 neutral) {
  vec3 pos = vec3(0.0), posPeak = vec3(0.0), neg = vec3(0.0), negPeak = vec3(0.0), lin = vec3(0.0);
  int start = int(rzRange.x + 0.5), count = int(rzRange.y + 0.5);
  for (int k = start; k < start + count; k++) {
    vec4 e = texelFetch(rzEntries, rzAt(k), 0);
    int code = int(e.x + 0.5);
    float amount = texelFetch(rzAmounts, rzAt(int(e.y + 0.5)), 0).r;
    int axis = code % 3;
    vec3 unit = axis == 0 ? vec3(1.0, 0.0, 0.0) : (axis == 1 ? vec3(0.0, 1.0, 0.0) : vec3(0.0, 0.0, 1.0));
    float push = e.z * amount;
    if (code >= 3) { lin += unit * push; continue; }
    float peak = e.w * abs(amount);
    if (push < 0.0) { neg -= unit * push; negPeak = max(negPeak, unit * peak); }
    else { pos += unit * push; posPeak = max(posPeak, unit * peak); }
  }
  vec3 p = neutral + min(pos, posPeak) - min(neg, negPeak) + lin;
  int ls = int(rzRange.z + 0.5), lc = int(rzRange.w + 0.5);
  for (int k = ls; k < ls + lc; k++) {
    vec4 l = texelFetch(rzLinks, rzAt(k), 0);
    vec3 moved = rzApply(int(l.x + 0.5), p);
    p += l.y * (moved - p);
  }
  return rzApply(rzGroupCount, p);
}
`;

function rows(count) { return Math.max(1, Math.ceil(count / TEXTURE_WIDTH)); }

// Float32Array texture data (RGBA per texel) of `count` texels of `stride` floats each.
export function texels(source, count, stride) {
  const out = new Float32Array(TEXTURE_WIDTH * rows(count) * 4);
  for (let i = 0; i < count; i++) {
    for (let c = 0; c < stride; c++) out[i * 4 + c] = source[i * stride + c];
  }
  return { data: out, width: TEXTURE_WIDTH, height: rows(count) };
}

// The static textures and the per-vertex attribute of a model.
export function gpuArrays(model) {
  return {
    entries: texels(model.entries, model.entries.length / 4, 4),
    links: texels(model.links, model.links.length / 2, 2),
    range: Float32Array.from(model.ranges),
  };
}

// Per-frame texture data: column amounts (RGBA, .r used) and the group maps (3 rows each).
export function frameArrays(model, faps) {
  const values = prepared(model, faps);
  const a = amounts(model, values);
  const amountTexels = texels(a, a.length, 1);
  const maps = groupMaps(model, values);
  const mapTexels = new Float32Array((model.groupCount + 1) * 3 * 4);
  mapTexels.set(maps);
  return { amounts: amountTexels, maps: { data: mapTexels, width: (model.groupCount + 1) * 3, height: 1 } };
}

function texture(gl, unit, { data, width, height }) {
  const t = gl.createTexture();
  gl.activeTexture(gl.TEXTURE0 + unit);
  gl.bindTexture(gl.TEXTURE_2D, t);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, width, height, 0, gl.RGBA, gl.FLOAT, data);
  return t;
}

// Runs GLSL_DEFORM on the GPU for each FAP vector of `fapsList` and reads the positions
// back through transform feedback: the shader the viewer draws with, checked value by value.
// Returns one Float32Array (n * 3) per vector.
export function deformTransformFeedback(gl, model, fapsList) {
  const vs = `#version 300 es
precision highp float; precision highp int;
${GLSL_DEFORM}
in vec3 rzNeutral;
out vec3 rzOut;
void main() { rzOut = rzDeform(rzNeutral); gl_Position = vec4(0.0); }`;
  const fs = `#version 300 es
precision highp float; out vec4 colour; void main() { colour = vec4(1.0); }`;
  function shader(kind, source) {
    const s = gl.createShader(kind);
    gl.shaderSource(s, source);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }
  const program = gl.createProgram();
  gl.attachShader(program, shader(gl.VERTEX_SHADER, vs));
  gl.attachShader(program, shader(gl.FRAGMENT_SHADER, fs));
  gl.transformFeedbackVaryings(program, ["rzOut"], gl.SEPARATE_ATTRIBS);
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
  gl.useProgram(program);
  const n = model.vertexCount;
  const arrays = gpuArrays(model);
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  function attribute(name, data, size) {
    const at = gl.getAttribLocation(program, name);
    const buffer = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
    gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(at);
    gl.vertexAttribPointer(at, size, gl.FLOAT, false, 0, 0);
  }
  attribute("rzNeutral", Float32Array.from(model.neutral), 3);
  attribute("rzRange", arrays.range, 4);
  texture(gl, 0, arrays.entries);
  texture(gl, 1, arrays.links);
  gl.uniform1i(gl.getUniformLocation(program, "rzEntries"), 0);
  gl.uniform1i(gl.getUniformLocation(program, "rzLinks"), 1);
  gl.uniform1i(gl.getUniformLocation(program, "rzAmounts"), 2);
  gl.uniform1i(gl.getUniformLocation(program, "rzMaps"), 3);
  gl.uniform1i(gl.getUniformLocation(program, "rzGroupCount"), model.groupCount);
  const out = gl.createBuffer();
  gl.bindBuffer(gl.TRANSFORM_FEEDBACK_BUFFER, out);
  gl.bufferData(gl.TRANSFORM_FEEDBACK_BUFFER, n * 12, gl.STREAM_READ);
  const feedback = gl.createTransformFeedback();
  gl.enable(gl.RASTERIZER_DISCARD);
  const results = [];
  for (const faps of fapsList) {
    const frame = frameArrays(model, faps);
    const ta = texture(gl, 2, frame.amounts);
    const tm = texture(gl, 3, frame.maps);
    gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, feedback);
    gl.bindBufferBase(gl.TRANSFORM_FEEDBACK_BUFFER, 0, out);
    gl.beginTransformFeedback(gl.POINTS);
    gl.drawArrays(gl.POINTS, 0, n);
    gl.endTransformFeedback();
    gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, null);
    const result = new Float32Array(n * 3);
    gl.bindBuffer(gl.TRANSFORM_FEEDBACK_BUFFER, out);
    gl.getBufferSubData(gl.TRANSFORM_FEEDBACK_BUFFER, 0, result);
    results.push(result);
    gl.deleteTexture(ta); gl.deleteTexture(tm);
  }
  gl.disable(gl.RASTERIZER_DISCARD);
  return results;
}
