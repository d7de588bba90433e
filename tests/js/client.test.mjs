// realizer-client.js under Node, against a real `realizer serve` (started by
// tests/service/test_js_client.py, which passes the URLs in the environment).
// Run: REALIZER_URL=ws://127.0.0.1:PORT REALIZER_GUARDED_URL=... node --test tests/js/
import { test } from "node:test";
import assert from "node:assert/strict";
import { createRequire } from "node:module";
import { readFileSync } from "node:fs";

import {
  SubmitClient, ViewClient, Unauthorized, Forbidden, ServerBusy, ServerUnavailable,
  ConnectionLost, ClientError, parseFeedback, decodeMsgpack,
} from "../../realizer/service/static/realizer-client.js";

const URL_ = process.env.REALIZER_URL;
const GUARDED = process.env.REALIZER_GUARDED_URL;  // --submit-token s3cret --view-token look --limit submitters=1
const DEAD = process.env.REALIZER_DEAD_URL;         // nothing listens there
const UNIT = Number(process.env.REALIZER_TEST_TIME_UNIT || "1");
const WebSocket = process.env.REALIZER_JS_WEBSOCKET === "ws"
  ? createRequire(import.meta.url)("ws")
  : globalThis.WebSocket;
const SMILE = readFileSync(new URL("../../examples/bml/01_smile.xml", import.meta.url), "utf8");
const LONG = '<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="long">'
  + '<head id="nod" lexeme="NOD" start="0" end="30"/></bml>';

test("a resting face comes as same messages, which frames() gives as the last frame again", async () => {
  const view = await ViewClient.connect(URL_, { character: "Rest", WebSocket });
  const old = await ViewClient.connect(URL_, { character: "Rest", same: false, WebSocket });
  try {
    const raw = [];
    for (let i = 0; i < 10; i++) raw.push(await view.receive(30000 * UNIT));
    const kinds = JSON.stringify(raw.map((m) => m.type));
    assert.equal(raw[0].type, "frame", kinds);  // the first whole, then (nothing moves) sames
    assert.ok(raw.slice(1).every((m) => m.type === "same" && m.v === 1), kinds);
    const frames = [];
    for await (const frame of view.frames(5, 30000 * UNIT)) frames.push(frame);
    assert.ok(frames.every((f) => f.type === "frame" && f.same === true));
    assert.ok(frames.slice(1).every((f, i) => f.n > frames[i].n && f.t > frames[i].t));
    // a client that does not ask for same gets whole frames
    for (let i = 0; i < 5; i++) assert.equal((await old.receive(30000 * UNIT)).type, "frame");
  } finally {
    view.close();
    old.close();
  }
});

test("a block runs to done with parsed feedback, and the viewer sees the face move", async () => {
  const view = await ViewClient.connect(URL_, { character: "Eve", vertices: "int16", WebSocket });
  const client = await SubmitClient.connect(URL_, { character: "Eve", WebSocket });
  assert.equal(client.welcome.protocol, 1);
  assert.ok(view.mesh.vertexCount > 0);
  const events = [];
  const running = client.runBlock(SMILE, { character: "Eve", onEvent: (e) => events.push(e),
    timeoutMs: 30000 * UNIT });
  let moved = 0;
  let lifted = false;
  const neutral = view.vertices({});
  for await (const frame of view.frames(Math.round(300 * UNIT), 30000 * UNIT)) {
    if (ViewClient.faps(frame).size) {
      moved++;
      const now = view.vertices(frame);
      lifted ||= now.some((x, i) => Math.abs(x - neutral[i]) > 1e-4);
    }
    if (moved > 5 && lifted) break;
  }
  assert.equal(await running, "done");
  assert.ok(moved > 0 && lifted, "no frame moved the face");
  const blocks = events.filter((e) => e.type === "block").map((e) => e.state);
  assert.deepEqual(blocks, ["accepted", "done"]);
  const syncs = events.filter((e) => e.type === "feedback" && e.kind === "syncPointProgress");
  assert.ok(syncs.length > 0);
  for (const e of syncs) {
    assert.equal(e.feedback.blockId, "smile");
    assert.equal(e.feedback.behaviourId, "smile1");
    assert.ok(Number.isFinite(e.feedback.globalTime));
  }
  const end = events.find((e) => e.type === "feedback" && e.feedback.element === "blockProgress"
    && e.feedback.sync === "end");
  assert.ok(end, "no blockProgress end");
  client.close();
  view.close();
});

test("an interrupt ends the block interrupted", async () => {
  const client = await SubmitClient.connect(URL_, { character: "Fred", WebSocket });
  client.submit(LONG);
  const states = [];
  for await (const event of client.events(30000 * UNIT)) {
    if (event.type !== "block") continue;
    states.push(event.state);
    if (event.state === "accepted") client.interrupt("long");
    if (event.final) break;
  }
  assert.deepEqual(states, ["accepted", "interrupted"]);
  client.close();
});

test("refusals are typed: 401, 403, busy, nothing listening", async () => {
  await assert.rejects(SubmitClient.connect(GUARDED, { WebSocket }), Unauthorized);
  await assert.rejects(SubmitClient.connect(GUARDED, { token: "look", WebSocket }), Forbidden);
  const view = await ViewClient.connect(GUARDED, { token: "look", WebSocket });
  view.close();
  const first = await SubmitClient.connect(GUARDED, { token: "s3cret", WebSocket });
  await assert.rejects(SubmitClient.connect(GUARDED, { token: "s3cret", WebSocket }),
    (error) => error instanceof ServerBusy && error.code === 1013);
  first.close();
  await assert.rejects(SubmitClient.connect(DEAD, { WebSocket }), ServerUnavailable);
  assert.ok(new ConnectionLost(1001, "bye") instanceof ClientError);
});

test("feedback XML and msgpack are read without a DOM", () => {
  const warning = parseFeedback(
    '<warningFeedback xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="b1" '
    + 'type="PARSING_FAILURE">a &lt;b&gt; &amp; c</warningFeedback>');
  assert.deepEqual(warning, { element: "warningFeedback", id: "b1", blockId: "b1",
    warningType: "PARSING_FAILURE", text: "a <b> & c" });
  // {"a": [1, -1, 300, 1.5], "b": bin 2}
  const bytes = Uint8Array.from([0x82, 0xa1, 0x61, 0x94, 0x01, 0xff, 0xcd, 0x01, 0x2c,
    0xcb, 0x3f, 0xf8, 0, 0, 0, 0, 0, 0, 0xa1, 0x62, 0xc4, 0x02, 7, 8]);
  const decoded = decodeMsgpack(bytes);
  assert.deepEqual(decoded.a, [1, -1, 300, 1.5]);
  assert.deepEqual([...decoded.b], [7, 8]);
  assert.throws(() => decodeMsgpack(Uint8Array.from([0xdd, 0xff, 0xff, 0xff, 0xff])), ClientError);
});

test("a target the client places is one a gaze can aim at", async () => {
  const client = await SubmitClient.connect(URL_, { character: "Gus", WebSocket });
  const gaze = (id) => '<bml xmlns="http://www.bml-initiative.org/bml/bml-1.0" id="' + id + '">'
    + '<gaze id="g" target="jsdoor" influence="EYES" start="0" end="0.3"/></bml>';
  const warnings = async (id) => {
    const seen = [];
    client.submit(gaze(id));
    for await (const event of client.events(30000 * UNIT)) {
      if (event.type === "feedback" && event.kind === "warning") seen.push(String(event.xml));
      if (event.type === "block" && event.blockId === id && event.final) break;
    }
    return seen.filter((xml) => xml.includes("NO_SUCH_TARGET"));
  };
  try {
    assert.equal((await warnings("before")).length, 1);  // no such target yet
    client.target("jsdoor", [2, 0, 1]);
    assert.deepEqual(await warnings("after"), []);
  } finally {
    client.close();
  }
});
