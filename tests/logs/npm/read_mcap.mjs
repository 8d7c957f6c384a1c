#!/usr/bin/env node
// Read an MCAP file with the reference MCAP library (@mcap/core's indexed
// reader: the footer, summary, chunk indexes and CRCs) and print, as one JSON
// line, its channels with their schema and message counts and, for JSON
// foxglove.SceneUpdate channels, the number of entities in the last message.
//
// usage: node read_mcap.mjs FILE.mcap
// Exits 77 when @mcap/core is not installed (scripts/install-deps.sh runs npm ci here), 1 when the file
// does not read.
import fs from "node:fs";
import path from "node:path";

let McapIndexedReader;
try {
  ({ McapIndexedReader } = await import("@mcap/core"));
} catch (e) {
  console.log(`read_mcap.mjs: SKIP: @mcap/core is not installed in ${path.dirname(new URL(import.meta.url).pathname)}: ${e.message}`);
  process.exit(77);
}

const file = process.argv[2];
if (!file) { console.log("usage: node read_mcap.mjs FILE.mcap"); process.exit(2); }
try {
  const fd = fs.openSync(file, "r");
  const size = fs.fstatSync(fd).size;
  const readable = {
    size: async () => BigInt(size),
    read: async (offset, length) => {
      const b = Buffer.alloc(Number(length));
      fs.readSync(fd, b, 0, Number(length), Number(offset));
      return new Uint8Array(b.buffer, b.byteOffset, b.length);
    },
  };
  const r = await McapIndexedReader.Initialize({ readable });
  const out = { channels: {}, messages: 0 };
  for (const [id, ch] of r.channelsById) {
    const sc = r.schemasById.get(ch.schemaId);
    out.channels[ch.topic] = { id, schema: sc ? sc.name : "", encoding: ch.messageEncoding, count: 0 };
  }
  const byId = new Map([...r.channelsById].map(([id, ch]) => [id, out.channels[ch.topic]]));
  const dec = new TextDecoder();
  for await (const m of r.readMessages()) {
    const c = byId.get(m.channelId);
    c.count++;
    out.messages++;
    if (c.schema === "foxglove.SceneUpdate" && c.encoding === "json") c.last_entities = JSON.parse(dec.decode(m.data)).entities.length;
  }
  out.statistics_messages = r.statistics ? Number(r.statistics.messageCount) : null;
  fs.closeSync(fd);
  console.log(JSON.stringify(out));
} catch (e) {
  console.log(`read_mcap.mjs: ${file}: ${e.message}`);
  process.exit(1);
}
