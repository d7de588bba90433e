// A msgpack decoder for the messages of the viewer endpoint (protocols/viewer.md):
// maps, arrays, strings, bin (returned as Uint8Array views), integers,
// floats, nil and booleans. Written for this project; no dependencies.
"use strict";
(function (global) {
  function decode(buffer) {
    const bytes = new Uint8Array(buffer);
    const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    const text = new TextDecoder();
    let at = 0;
    function str(n) { const s = text.decode(bytes.subarray(at, at + n)); at += n; return s; }
    function bin(n) { const b = bytes.subarray(at, at + n); at += n; return b; }
    function arr(n) { const a = new Array(n); for (let i = 0; i < n; i++) a[i] = read(); return a; }
    function map(n) { const m = {}; for (let i = 0; i < n; i++) { const k = read(); m[k] = read(); } return m; }
    function read() {
      const t = bytes[at++];
      if (t <= 0x7f) return t;
      if (t <= 0x8f) return map(t & 0x0f);
      if (t <= 0x9f) return arr(t & 0x0f);
      if (t <= 0xbf) return str(t & 0x1f);
      if (t >= 0xe0) return t - 0x100;
      let v;
      switch (t) {
        case 0xc0: return null;
        case 0xc2: return false;
        case 0xc3: return true;
        case 0xc4: v = bytes[at]; at += 1; return bin(v);
        case 0xc5: v = view.getUint16(at); at += 2; return bin(v);
        case 0xc6: v = view.getUint32(at); at += 4; return bin(v);
        case 0xca: v = view.getFloat32(at); at += 4; return v;
        case 0xcb: v = view.getFloat64(at); at += 8; return v;
        case 0xcc: v = bytes[at]; at += 1; return v;
        case 0xcd: v = view.getUint16(at); at += 2; return v;
        case 0xce: v = view.getUint32(at); at += 4; return v;
        case 0xcf: v = Number(view.getBigUint64(at)); at += 8; return v;
        case 0xd0: v = view.getInt8(at); at += 1; return v;
        case 0xd1: v = view.getInt16(at); at += 2; return v;
        case 0xd2: v = view.getInt32(at); at += 4; return v;
        case 0xd3: v = Number(view.getBigInt64(at)); at += 8; return v;
        case 0xd9: v = bytes[at]; at += 1; return str(v);
        case 0xda: v = view.getUint16(at); at += 2; return str(v);
        case 0xdb: v = view.getUint32(at); at += 4; return str(v);
        case 0xdc: v = view.getUint16(at); at += 2; return arr(v);
        case 0xdd: v = view.getUint32(at); at += 4; return arr(v);
        case 0xde: v = view.getUint16(at); at += 2; return map(v);
        case 0xdf: v = view.getUint32(at); at += 4; return map(v);
      }
      throw new Error("msgpack type 0x" + t.toString(16) + " is not used by this protocol");
    }
    return read();
  }
  global.msgpackDecode = decode;
})(window);
