// Reads MCAP files with Foxglove's own libraries, as Foxglove Studio does: @mcap/core's indexed
// reader with @mcap/support's decompressors, each channel's ros2msg schema parsed by
// @foxglove/rosmsg and every message decoded by @foxglove/rosmsg2-serialization. For
// sensor_msgs/msg/PointCloud2 it also checks what Foxglove's 3D panel needs: float32 fields x,
// y, z inside point_step, and data of width x height x point_step bytes.
//
// usage: node read_mcap.mjs FILE.mcap...   prints one JSON line per file; exit 1 on any failure.
import { McapIndexedReader } from "@mcap/core";
import { loadDecompressHandlers } from "@mcap/support";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { open } from "node:fs/promises";

const FLOAT32 = 7;

function checkCloud(msg) {
  const fields = new Map(msg.fields.map((f) => [f.name, f]));
  for (const name of ["x", "y", "z"]) {
    const f = fields.get(name);
    if (!f) return `no field ${name}`;
    if (f.datatype !== FLOAT32) return `field ${name} is datatype ${f.datatype}, not FLOAT32`;
    if (f.offset + 4 > msg.point_step) return `field ${name} lies outside point_step`;
  }
  if (msg.data.length !== msg.width * msg.height * msg.point_step)
    return `data has ${msg.data.length} bytes, width*height*point_step is ${msg.width * msg.height * msg.point_step}`;
  if (msg.row_step !== msg.width * msg.point_step) return `row_step ${msg.row_step} != width*point_step`;
  return null;
}

async function readFile(path, decompressHandlers) {
  const handle = await open(path, "r");
  const readable = {
    size: async () => BigInt((await handle.stat()).size),
    read: async (offset, length) => {
      const buf = new Uint8Array(Number(length));
      await handle.read(buf, 0, Number(length), Number(offset));
      return buf;
    },
  };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  const readers = new Map();
  const topics = {};
  for (const [id, channel] of reader.channelsById) {
    const schema = reader.schemasById.get(channel.schemaId);
    const t = (topics[channel.topic] = {
      schema: schema?.name,
      messages: 0,
      errors: [],
      fields: null,
      points: 0,
    });
    if (!schema || schema.encoding !== "ros2msg" || channel.messageEncoding !== "cdr") {
      t.errors.push(`schema encoding ${schema?.encoding}, message encoding ${channel.messageEncoding}`);
      continue;
    }
    try {
      readers.set(id, new MessageReader(parse(new TextDecoder().decode(schema.data), { ros2: true })));
    } catch (e) {
      t.errors.push(`schema does not parse: ${e}`);
    }
  }
  for await (const m of reader.readMessages()) {
    const channel = reader.channelsById.get(m.channelId);
    const t = topics[channel.topic];
    t.messages += 1;
    const r = readers.get(m.channelId);
    if (!r) continue;
    try {
      const msg = r.readMessage(m.data);
      if (t.schema === "sensor_msgs/msg/PointCloud2") {
        const err = checkCloud(msg);
        if (err && t.errors.length < 5) t.errors.push(err);
        t.fields = msg.fields.map((f) => f.name);
        t.points += msg.width * msg.height;
      }
    } catch (e) {
      if (t.errors.length < 5) t.errors.push(`message ${t.messages} does not decode: ${e}`);
    }
  }
  await handle.close();
  const expected = Object.fromEntries(
    [...reader.channelsById.values()].map((c) => [c.topic, 0])
  );
  for (const s of reader.statistics ? [reader.statistics] : []) {
    for (const [id, n] of s.channelMessageCounts) {
      expected[reader.channelsById.get(id).topic] = Number(n);
    }
  }
  let ok = true;
  for (const [topic, t] of Object.entries(topics)) {
    t.expected = expected[topic];
    if (t.errors.length > 0 || t.messages !== t.expected) ok = false;
  }
  return { file: path, ok, topics };
}

const decompressHandlers = await loadDecompressHandlers();
let failed = false;
for (const path of process.argv.slice(2)) {
  try {
    const r = await readFile(path, decompressHandlers);
    console.log(JSON.stringify(r));
    if (!r.ok) failed = true;
  } catch (e) {
    console.log(JSON.stringify({ file: path, ok: false, error: String(e) }));
    failed = true;
  }
}
process.exit(failed ? 1 : 0);
