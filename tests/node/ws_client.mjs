// Foxglove's own WebSocket client library (`@foxglove/ws-protocol`'s FoxgloveClient) against
// `tilting live/replay/view --foxglove`, offering one subprotocol, subscribing to every channel
// the server advertises and decoding every message with its advertised schema (schemas.mjs).
//
// Usage: node ws_client.mjs --url ws://127.0.0.1:PORT --subprotocol NAME --seconds S --out FILE
//
// Under `foxglove.sdk.v1` the advertisement carries each channel's schema inline, as
// FoxgloveClient 0.8.0 expects. Under `foxglove.sdk.v1.1` (Foxglove SDK 0.30) it carries a
// connection-scoped schema table (`schemas: [{id, name, encoding, data}]`, each channel a
// `schemaId`), which FoxgloveClient 0.8.0 drops (its `advertise` event passes the channels
// only): this client reads the table from the same socket's text frames, as a v1.1 viewer must,
// and records per channel whether the library alone would have had the schema.
//
// It connects (retrying until --seconds pass), collects until the server closes or --seconds
// pass, and writes JSON: the subprotocol, per topic the schema's name, encoding and origin and
// the messages decoded, the first errors, the states' seq and log time, the log entries, the
// scene's entity ids, and the plot channel's ticks with their log times. A refused handshake is written as {"refused": HTTP status}.

import wsp from "@foxglove/ws-protocol";
import { writeFileSync } from "node:fs";
import WebSocket from "ws";
import { decoder } from "./schemas.mjs";

const { FoxgloveClient } = wsp;

function args() {
  const a = { seconds: 30 };
  const argv = process.argv.slice(2);
  for (let i = 0; i < argv.length; i += 2) {
    const k = argv[i].replace(/^--/, "");
    if (!["url", "subprotocol", "seconds", "out"].includes(k) || argv[i + 1] === undefined) {
      console.error(`ws_client.mjs: bad argument ${argv[i]}`);
      process.exit(2);
    }
    a[k] = k === "seconds" ? Number(argv[i + 1]) : argv[i + 1];
  }
  for (const k of ["url", "subprotocol", "out"]) {
    if (a[k] === undefined) {
      console.error(`ws_client.mjs: --${k} is required`);
      process.exit(2);
    }
  }
  return a;
}

/**
 * Connects, retrying while the server is not listening yet; the client's handlers are in place
 * before the socket opens (the server's first frames may arrive with the handshake's answer).
 */
async function connect(a, out, deadline) {
  for (;;) {
    const ws = new WebSocket(a.url, [a.subprotocol]);
    const table = new Map();
    // Registered before FoxgloveClient's handler: sees each advertisement's schema table first.
    ws.on("message", (data, isBinary) => {
      if (isBinary) return;
      const m = JSON.parse(data.toString());
      if (m.op === "serverInfo") table.clear();
      if (m.op === "advertise") for (const s of m.schemas ?? []) table.set(s.id, s);
    });
    const client = new FoxgloveClient({ ws });
    const r = await new Promise((resolve) => {
      const closed = new Promise((res) => client.on("close", () => res("closed")));
      ws.once("open", () => resolve({ ws, closed }));
      ws.once("unexpected-response", (_req, res) => resolve({ refused: res.statusCode }));
      ws.once("error", (e) => resolve({ error: e }));
      if (out !== undefined) listen(client, table, out);
    });
    if (r.ws !== undefined || r.refused !== undefined) return r;
    if (Date.now() > deadline) throw r.error;
    await new Promise((res) => setTimeout(res, 50));
  }
}

function b64(s) {
  return new Uint8Array(Buffer.from(s, "base64"));
}

/** The schema of an advertised channel: inline (v1) or from the connection's table (v1.1). */
function schemaOf(ch, table) {
  if (typeof ch.schema === "string") {
    const enc = ch.schemaEncoding ?? "";
    const data = enc === "protobuf" ? b64(ch.schema) : new TextEncoder().encode(ch.schema);
    return { from: "inline", name: ch.schemaName, encoding: enc, data };
  }
  const t = table.get(ch.schemaId);
  if (t === undefined) return undefined;
  const data = t.encoding === "protobuf" ? b64(t.data) : new TextEncoder().encode(t.data);
  return { from: "table", name: t.name, encoding: t.encoding, data };
}

function listen(client, table, out) {
  const subs = new Map();
  client.on("serverInfo", (info) => {
    out.serverInfo = { name: info.name, capabilities: info.capabilities };
  });
  client.on("advertise", (channels) => {
    for (const ch of channels) {
      const topic = { encoding: ch.encoding, libraryHasSchema: typeof ch.schema === "string" };
      topic.count = 0;
      topic.errors = [];
      out.topics[ch.topic] = topic;
      const schema = schemaOf(ch, table);
      if (schema === undefined) {
        topic.errors.push(`no schema for channel ${ch.id} (schemaId ${ch.schemaId})`);
        continue;
      }
      Object.assign(topic, { schemaName: schema.name, schemaEncoding: schema.encoding });
      topic.schemaFrom = schema.from;
      let decode;
      try {
        decode = decoder(ch.encoding, schema);
      } catch (e) {
        topic.errors.push(`schema: ${e.message}`);
        continue;
      }
      subs.set(client.subscribe(ch.id), { topic: ch.topic, decode });
    }
  });
  client.on("message", ({ subscriptionId, timestamp, data }) => {
    const s = subs.get(subscriptionId);
    if (s === undefined) return;
    const t = out.topics[s.topic];
    const bytes = new Uint8Array(data.buffer, data.byteOffset, data.byteLength);
    let m;
    try {
      m = s.decode(bytes);
    } catch (e) {
      if (t.errors.length < 5) t.errors.push(e.message);
      return;
    }
    t.count += 1;
    record(out, s.topic, m, timestamp);
  });
}

/** Keeps what the Rust test compares: states, log entries, scene entity ids, plot ticks. */
function record(out, topic, m, logTime) {
  if (topic.endsWith("/plot")) {
    out.plots.push({ ...m, log_time: Number(logTime) });
  } else if (topic.endsWith("/plant/state")) {
    out.states.push({ seq: m.seq, time: m.time, mode: m.mode, mode_name: m.mode_name,
      log_time: Number(logTime) });
  } else if (topic.endsWith("/log")) {
    out.logs.push({ level: m.level, message: m.message, sec: m.timestamp.seconds,
      nsec: m.timestamp.nanos, log_time: Number(logTime) });
  } else if (topic.endsWith("/scene")) {
    for (const e of m.entities) {
      if (!out.sceneEntityIds.includes(e.id)) out.sceneEntityIds.push(e.id);
    }
  } else if (topic.endsWith("/plant/event") && out.events.length < 50) {
    out.events.push({ from: m.from, to: m.to, from_name: m.from_name, to_name: m.to_name });
  }
}

const a = args();
const deadline = Date.now() + a.seconds * 1000;
const out = {
  subprotocol: null, topics: {}, states: [], logs: [], events: [], sceneEntityIds: [], plots: [],
};
const r = await connect(a, out, deadline);
if (r.refused !== undefined) {
  out.refused = r.refused;
} else {
  out.subprotocol = r.ws.protocol;
  const timeout = new Promise((res) => setTimeout(() => res("deadline"), deadline - Date.now()));
  out.end = await Promise.race([r.closed, timeout]);
  r.ws.terminate();
}
writeFileSync(a.out, JSON.stringify(out));
process.exit(0);
