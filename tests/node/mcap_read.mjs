// Foxglove's MCAP library (`@mcap/core`'s McapIndexedReader, with `@mcap/support`'s
// decompressors, as Foxglove's and Lichtblick's file readers use them) on a recording: reads the
// summary and every message through the chunk and message indexes, and decodes each message
// with its channel's schema as the viewers do (schemas.mjs: the strict JSON Schema check).
//
// Usage: node mcap_read.mjs FILE.mcap
//
// Prints JSON: the statistics' message count, per topic the schema, the messages read and the
// first errors, whether log times never went backwards within a topic, and the first and last
// log time.

import { McapIndexedReader } from "@mcap/core";
import { loadDecompressHandlers } from "@mcap/support";
import { open } from "node:fs/promises";
import { decoder } from "./schemas.mjs";

const path = process.argv[2];
if (path === undefined) {
  console.error("usage: node mcap_read.mjs FILE.mcap");
  process.exit(2);
}
const file = await open(path, "r");
const readable = {
  size: async () => BigInt((await file.stat()).size),
  read: async (offset, size) => {
    const buf = new Uint8Array(Number(size));
    const { bytesRead } = await file.read(buf, 0, Number(size), Number(offset));
    if (bytesRead !== Number(size)) throw new Error(`short read at ${offset}`);
    return buf;
  },
};
const reader = await McapIndexedReader.Initialize({
  readable,
  decompressHandlers: await loadDecompressHandlers(),
});
const out = {
  statisticsMessageCount: reader.statistics ? Number(reader.statistics.messageCount) : null,
  chunks: reader.chunkIndexes.length,
  topics: {},
  total: 0,
};
const decoders = new Map();
for (const [id, ch] of reader.channelsById) {
  const schema = reader.schemasById.get(ch.schemaId);
  const t = { messageEncoding: ch.messageEncoding, count: 0, errors: [], monotonic: true };
  Object.assign(t, { schemaName: schema?.name, schemaEncoding: schema?.encoding });
  out.topics[ch.topic] = t;
  try {
    decoders.set(id, decoder(ch.messageEncoding, schema));
  } catch (e) {
    t.errors.push(`schema: ${e.message}`);
  }
}
const last = new Map();
for await (const m of reader.readMessages()) {
  out.total += 1;
  const ch = reader.channelsById.get(m.channelId);
  const t = out.topics[ch.topic];
  const prev = last.get(m.channelId);
  if (prev !== undefined && m.logTime < prev) t.monotonic = false;
  last.set(m.channelId, m.logTime);
  out.first_log_time ??= Number(m.logTime);
  out.last_log_time = Number(m.logTime);
  const decode = decoders.get(m.channelId);
  if (decode === undefined) continue;
  try {
    decode(m.data);
    t.count += 1;
  } catch (e) {
    if (t.errors.length < 5) t.errors.push(e.message);
  }
}
await file.close();
console.log(JSON.stringify(out));
