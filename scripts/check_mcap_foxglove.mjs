// Reads an MCAP file written by `slam run --mcap` the way Foxglove opens a local file, with
// Foxglove's own TypeScript libraries (npm: @mcap/core, @mcap/support, @foxglove/rosmsg,
// @foxglove/rosmsg2-serialization), and checks what `ros2 bag play` needs from it.
//
//   node check_mcap_foxglove.mjs FILE.mcap [--topics /a,/b] [--out RUN_FOLDER]
//
// Checks (each failure is printed; the exit status is 1 if any):
// * a streaming pass over every record with CRC validation (chunks' CRCs): the file parses
//   from the magic to the footer; the header's profile is `ros2`;
// * the indexed reader (the one Foxglove uses for local files) initialises from the summary:
//   chunk indexes, schemas, channels and a Statistics record (rosbag2's MCAP storage needs
//   it) whose message count, per-channel counts and start/end times are those of the
//   streaming pass;
// * every schema is `ros2msg` with a `pkg/msg/Type` name and parses as a ROS 2 definition;
//   every channel is `cdr` and carries `offered_qos_profiles` (integer form: reliable, keep
//   last; /map and /tf_static transient local with depth 1, the others volatile);
// * every message, read through the indexes in log-time order with CRC validation,
//   decodes with its channel's schema using every byte (no trailing bytes: the definition
//   and the bytes agree), and log times never step back;
// * --topics: exactly these topics; --out: the last /map has the size of map.pgm and the
//   resolution and origin of map.yaml, with width·height cells.
import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { loadDecompressHandlers } from "@mcap/support";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { open, readFile } from "node:fs/promises";
import { join } from "node:path";

const args = process.argv.slice(2);
const file = args[0];
const opt = (name) => {
  const k = args.indexOf(name);
  return k >= 0 ? args[k + 1] : undefined;
};
const problems = [];
const fail = (what) => problems.push(what);

const decompressHandlers = await loadDecompressHandlers();

// 1. Streaming pass over every record, CRCs validated.
const bytes = new Uint8Array(await readFile(file));
const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
stream.append(bytes);
let header;
let footer;
const streamCounts = new Map();
let streamMessages = 0n;
let minTime;
let maxTime;
for (let r; (r = stream.nextRecord()); ) {
  if (r.type === "Header") header = r;
  if (r.type === "Footer") footer = r;
  if (r.type === "Message") {
    streamMessages += 1n;
    streamCounts.set(r.channelId, (streamCounts.get(r.channelId) ?? 0n) + 1n);
    if (minTime === undefined || r.logTime < minTime) minTime = r.logTime;
    if (maxTime === undefined || r.logTime > maxTime) maxTime = r.logTime;
  }
}
if (!stream.done()) fail(`the streaming reader stopped with ${stream.bytesRemaining()} byte(s) left`);
if (!header || !footer) fail("no header or no footer record");
if (header && header.profile !== "ros2") fail(`profile ${JSON.stringify(header.profile)}, expected "ros2"`);

// 2. The indexed reader, from the summary.
const fh = await open(file, "r");
const readable = {
  size: async () => BigInt((await fh.stat()).size),
  read: async (offset, size) => {
    const buf = new Uint8Array(Number(size));
    const { bytesRead } = await fh.read(buf, 0, Number(size), Number(offset));
    if (bytesRead !== Number(size)) throw new Error(`short read at ${offset}`);
    return buf;
  },
};
const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
const stats = reader.statistics;
if (!stats) fail("no Statistics record in the summary (rosbag2's MCAP storage needs one)");
if (reader.chunkIndexes.length === 0) fail("no chunk indexes in the summary");
if (stats) {
  if (stats.messageCount !== streamMessages)
    fail(`Statistics messageCount ${stats.messageCount}, the file holds ${streamMessages}`);
  if (stats.messageStartTime !== minTime || stats.messageEndTime !== maxTime)
    fail(`Statistics times ${stats.messageStartTime}…${stats.messageEndTime}, messages ${minTime}…${maxTime}`);
  for (const [id, n] of streamCounts) {
    if (stats.channelMessageCounts.get(id) !== n)
      fail(`channel ${id}: Statistics count ${stats.channelMessageCounts.get(id)}, the file holds ${n}`);
  }
  if (stats.channelCount !== reader.channelsById.size) fail("Statistics channelCount differs");
  if (stats.schemaCount !== reader.schemasById.size) fail("Statistics schemaCount differs");
}

// 3. Schemas and channels.
const readers = new Map();
for (const [id, s] of reader.schemasById) {
  if (s.encoding !== "ros2msg") fail(`schema ${s.name}: encoding ${s.encoding}, expected ros2msg`);
  if (!/^[A-Za-z0-9_]+\/msg\/[A-Za-z0-9_]+$/.test(s.name)) fail(`schema name ${s.name} is not pkg/msg/Type`);
  try {
    readers.set(id, new MessageReader(parse(new TextDecoder().decode(s.data), { ros2: true })));
  } catch (e) {
    fail(`schema ${s.name} does not parse: ${e.message}`);
  }
}
const topics = new Map();
for (const [id, c] of reader.channelsById) {
  topics.set(c.topic, c);
  if (c.messageEncoding !== "cdr") fail(`${c.topic}: message encoding ${c.messageEncoding}, expected cdr`);
  const qos = c.metadata.get("offered_qos_profiles");
  if (!qos) {
    fail(`${c.topic}: no offered_qos_profiles metadata`);
    continue;
  }
  const field = (k) => Number((qos.match(new RegExp(`\\b${k}: (\\d+)`)) ?? [])[1]);
  const latched = c.topic === "/map" || c.topic === "/tf_static";
  const want = { history: 1, reliability: 1, durability: latched ? 1 : 2, depth: latched ? 1 : 10 };
  for (const [k, v] of Object.entries(want)) {
    if (field(k) !== v) fail(`${c.topic}: QoS ${k} ${field(k)}, expected ${v}`);
  }
}
const wanted = opt("--topics");
if (wanted) {
  const want = wanted.split(",").sort().join(",");
  const have = [...topics.keys()].sort().join(",");
  if (want !== have) fail(`topics ${have}, expected ${want}`);
}

// 4. Every message, through the indexes, decoded.
const decoded = new Map();
let lastMap;
let last = -1n;
let n = 0n;
for await (const m of reader.readMessages({ validateCrcs: true })) {
  n += 1n;
  const c = reader.channelsById.get(m.channelId);
  if (m.logTime < last) fail(`${c.topic}: log time ${m.logTime} before ${last}`);
  last = m.logTime;
  const r = readers.get(c.schemaId);
  if (!r) continue;
  try {
    const msg = r.readMessage(m.data);
    if (r.lastReadHadTrailingBytes()) {
      fail(`${c.topic} message ${m.sequence}: ${m.data.length - r.lastReadByteLength()} trailing byte(s)`);
    }
    decoded.set(c.topic, (decoded.get(c.topic) ?? 0) + 1);
    if (c.topic === "/map") lastMap = msg;
  } catch (e) {
    fail(`${c.topic} message ${m.sequence} does not decode: ${e.message}`);
  }
}
if (n !== streamMessages) fail(`the indexes reach ${n} message(s), the file holds ${streamMessages}`);

// 5. The last map against the run's map.yaml and map.pgm.
const out = opt("--out");
if (out && topics.has("/map")) {
  const yaml = await readFile(join(out, "map.yaml"), "utf8");
  const resolution = Number(yaml.match(/resolution: *([-\d.e]+)/)[1]);
  const origin = yaml.match(/origin: *\[([^\]]*)\]/)[1].split(",").map(Number);
  const pgm = new TextDecoder().decode((await readFile(join(out, "map.pgm"))).subarray(0, 64));
  const [, w, h] = pgm.match(/^P5\s+(?:#[^\n]*\n\s*)*(\d+)\s+(\d+)/);
  const info = lastMap.info;
  if (info.width !== Number(w) || info.height !== Number(h))
    fail(`/map ${info.width}×${info.height}, map.pgm ${w}×${h}`);
  if (lastMap.data.length !== info.width * info.height) fail("/map data is not width·height cells");
  if (Math.abs(info.resolution - resolution) > 1e-6 * resolution) fail(`/map resolution ${info.resolution}, map.yaml ${resolution}`);
  const o = info.origin.position;
  if (Math.abs(o.x - origin[0]) > 1e-6 || Math.abs(o.y - origin[1]) > 1e-6)
    fail(`/map origin (${o.x}, ${o.y}), map.yaml (${origin[0]}, ${origin[1]})`);
}
await fh.close();

const summary = [...decoded].map(([t, k]) => `${t} ${k}`).join(", ");
if (problems.length) {
  for (const p of problems) console.error(`${file}: ${p}`);
  process.exit(1);
}
console.log(`${file}: Foxglove's readers: ${streamMessages} message(s) decoded (${summary}); profile ros2, CRCs, statistics, QoS ok`);
