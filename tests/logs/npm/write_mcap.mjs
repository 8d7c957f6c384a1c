#!/usr/bin/env node
// Write the frames of a YCB-Video folder as a ROS 2 MCAP file with the reference
// MCAP library (@mcap/core), independently of sooc3d.
//
// usage: node write_mcap.mjs SEQ_DIR OUT.mcap [N] [--folder DIR]
//
// SEQ_DIR holds NNNNNN-color.png (RGB8), NNNNNN-depth.png (16-bit, metres =
// value / factor_depth) and NNNNNN-meta.mat (MATLAB v5: intrinsic_matrix,
// factor_depth, rotation_translation_matrix world-to-camera). The PNG and MAT
// files are decoded here (Node's zlib); the messages are serialised here as
// ROS 2 CDR (little endian):
//   /tf_static                               tf2_msgs/msg/TFMessage      map -> world (identity)
//   /tf                                      tf2_msgs/msg/TFMessage      world -> camera_color_optical_frame
//   /camera/color/camera_info                sensor_msgs/msg/CameraInfo  K of meta.mat
//   /camera/color/image_raw                  sensor_msgs/msg/Image       rgb8
//   /camera/aligned_depth_to_color/image_raw sensor_msgs/msg/Image       32FC1 metres (value * (1 / factor))
// Stamps: frame number x 33333333 ns (the folder reader's). Chunks are not
// compressed (Node 20's zlib has no zstd or lz4). With --folder DIR the same
// frames are also written as a 7-Scenes layout folder (links to the PNGs, a
// calib.yaml with K and depth_scale 1 / factor_depth, and pose files holding
// the rotation the log's quaternion stands for, computed as sooc_quat_to_m3
// does): a recorded rotation that is not exactly orthonormal cannot survive a
// quaternion, so folder and log hold the same frames. Exits 77 when
// @mcap/core is not installed (scripts/install-deps.sh runs npm ci here).
import fs from "node:fs";
import path from "node:path";
import zlib from "node:zlib";

let McapWriter;
try {
  ({ McapWriter } = await import("@mcap/core"));
} catch (e) {
  console.log(`write_mcap.mjs: SKIP: @mcap/core is not installed in ${path.dirname(new URL(import.meta.url).pathname)} ` +
              `(bash scripts/install-deps.sh runs npm ci there): ${e.message}`);
  process.exit(77);
}

// ------------------------------------------------------------------ PNG
function paeth(a, b, c) {
  const p = a + b - c, pa = Math.abs(p - a), pb = Math.abs(p - b), pc = Math.abs(p - c);
  return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
}

function readPng(file) {
  const d = fs.readFileSync(file);
  if (d.readUInt32BE(0) !== 0x89504e47) throw new Error(`${file}: not a PNG`);
  let off = 8, w = 0, h = 0, depth = 0, ctype = 0;
  const idat = [];
  while (off + 8 <= d.length) {
    const len = d.readUInt32BE(off), type = d.toString("latin1", off + 4, off + 8);
    const body = d.subarray(off + 8, off + 8 + len);
    if (type === "IHDR") {
      w = body.readUInt32BE(0); h = body.readUInt32BE(4); depth = body[8]; ctype = body[9];
      if (body[12] !== 0) throw new Error(`${file}: interlaced PNG`);
    } else if (type === "IDAT") idat.push(body);
    else if (type === "IEND") break;
    off += 12 + len;
  }
  const chans = { 0: 1, 2: 3, 6: 4 }[ctype];
  if (!chans || (depth !== 8 && depth !== 16)) throw new Error(`${file}: colour type ${ctype}, depth ${depth}`);
  const bpp = chans * depth / 8, stride = w * bpp;
  const raw = zlib.inflateSync(Buffer.concat(idat));
  const out = Buffer.alloc(h * stride);
  for (let y = 0; y < h; y++) {
    const f = raw[y * (stride + 1)], src = raw.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
    const row = out.subarray(y * stride, (y + 1) * stride), prev = y > 0 ? out.subarray((y - 1) * stride, y * stride) : null;
    for (let x = 0; x < stride; x++) {
      const a = x >= bpp ? row[x - bpp] : 0, b = prev ? prev[x] : 0, c = prev && x >= bpp ? prev[x - bpp] : 0;
      const pr = f === 0 ? 0 : f === 1 ? a : f === 2 ? b : f === 3 ? (a + b) >> 1 : f === 4 ? paeth(a, b, c) : -1;
      if (pr < 0) throw new Error(`${file}: filter ${f}`);
      row[x] = (src[x] + pr) & 255;
    }
  }
  return { w, h, chans, depth, data: out };
}

// ------------------------------------------------------------------ MAT v5
const MAT_TYPES = { 1: ["getInt8", 1], 2: ["getUint8", 1], 3: ["getInt16", 2], 4: ["getUint16", 2], 5: ["getInt32", 4],
                    6: ["getUint32", 4], 7: ["getFloat32", 4], 9: ["getFloat64", 8], 12: ["getBigInt64", 8],
                    13: ["getBigUint64", 8] };

function* matElements(buf, off, end) {
  while (off + 8 <= end) {
    let type = buf.readUInt32LE(off), size, data;
    if (type >>> 16) { size = type >>> 16; type &= 0xffff; data = buf.subarray(off + 4, off + 4 + size); off += 8; }
    else { size = buf.readUInt32LE(off + 4); data = buf.subarray(off + 8, off + 8 + size); off += 8 + size;
           if (type !== 15) off += (8 - (size % 8)) % 8; }
    yield { type, data };
  }
}

function matNumbers(el) {
  const [get, n] = MAT_TYPES[el.type] || [];
  if (!get) throw new Error(`MAT type ${el.type}`);
  const v = new DataView(el.data.buffer, el.data.byteOffset, el.data.byteLength), out = [];
  for (let i = 0; i + n <= el.data.length; i += n) out.push(Number(v[get](i, true)));
  return out;
}

function readMat(file, want) {
  const d = fs.readFileSync(file), vars = {};
  if (d.readUInt16LE(126) !== 0x4d49) throw new Error(`${file}: not a little-endian MAT v5 file`);
  for (let el of matElements(d, 128, d.length)) {
    if (el.type === 15) el = matElements(zlib.inflateSync(el.data), 0, Infinity).next().value;
    if (el.type !== 14) continue;
    const sub = [...matElements(el.data, 0, el.data.length)];
    const name = sub[2].data.toString("latin1");
    if (want.includes(name)) vars[name] = { dims: matNumbers(sub[1]), v: matNumbers(sub[3]) };
  }
  for (const k of want) if (!vars[k]) throw new Error(`${file}: no variable ${k}`);
  return vars;
}

// ------------------------------------------------------------------ CDR (little endian)
class Cdr {
  constructor() { this.b = Buffer.alloc(1 << 16); this.n = 4; this.b.writeUInt32BE(0x00010000, 0); }
  room(k) { if (this.n + k > this.b.length) { const nb = Buffer.alloc(Math.max(2 * this.b.length, this.n + k)); this.b.copy(nb); this.b = nb; } }
  align(a) { const o = (this.n - 4) % a; if (o) { this.room(a - o); this.b.fill(0, this.n, this.n + a - o); this.n += a - o; } }
  u8(v) { this.room(1); this.b[this.n++] = v; }
  u32(v) { this.align(4); this.room(4); this.b.writeUInt32LE(v, this.n); this.n += 4; }
  i32(v) { this.align(4); this.room(4); this.b.writeInt32LE(v, this.n); this.n += 4; }
  f64(v) { this.align(8); this.room(8); this.b.writeDoubleLE(v, this.n); this.n += 8; }
  str(s) { const e = Buffer.from(s + "\0", "utf8"); this.u32(e.length); this.room(e.length); e.copy(this.b, this.n); this.n += e.length; }
  bytes(d) { this.u32(d.length); this.room(d.length); Buffer.from(d.buffer, d.byteOffset, d.byteLength).copy(this.b, this.n); this.n += d.length; }
  header(t, frame) { this.i32(Number(t / 1000000000n)); this.u32(Number(t % 1000000000n)); this.str(frame); }
  done() { return new Uint8Array(this.b.subarray(0, this.n)); }
}

function cdrTf(items) {
  const c = new Cdr();
  c.u32(items.length);
  for (const [t, parent, child, tr, q] of items) {
    c.header(t, parent); c.str(child);
    for (const v of tr) c.f64(v);
    for (const v of q) c.f64(v);
  }
  return c.done();
}

function cdrCamInfo(t, frame, w, h, K) {
  const c = new Cdr();
  c.header(t, frame); c.u32(h); c.u32(w); c.str("plumb_bob");
  c.u32(5); for (let i = 0; i < 5; i++) c.f64(0);
  for (const v of K) c.f64(v);
  for (const v of [1, 0, 0, 0, 1, 0, 0, 0, 1]) c.f64(v);
  for (const v of [K[0], K[1], K[2], 0, K[3], K[4], K[5], 0, K[6], K[7], K[8], 0]) c.f64(v);
  c.u32(0); c.u32(0); c.u32(0); c.u32(0); c.u32(0); c.u32(0); c.u8(0);
  return c.done();
}

function cdrImage(t, frame, w, h, enc, data) {
  const c = new Cdr();
  c.header(t, frame); c.u32(h); c.u32(w); c.str(enc); c.u8(0); c.u32(data.length / h); c.bytes(data);
  return c.done();
}

// Rotation matrix (rows) -> (x, y, z, w) with w >= 0, as tests/logs/write_bag.py.
function quat(R) {
  const tr = R[0][0] + R[1][1] + R[2][2];
  let w, x, y, z, s;
  if (tr > 0) { s = Math.sqrt(tr + 1) * 2; w = 0.25 * s; x = (R[2][1] - R[1][2]) / s; y = (R[0][2] - R[2][0]) / s; z = (R[1][0] - R[0][1]) / s; }
  else if (R[0][0] > R[1][1] && R[0][0] > R[2][2]) { s = Math.sqrt(1 + R[0][0] - R[1][1] - R[2][2]) * 2; w = (R[2][1] - R[1][2]) / s; x = 0.25 * s; y = (R[0][1] + R[1][0]) / s; z = (R[0][2] + R[2][0]) / s; }
  else if (R[1][1] > R[2][2]) { s = Math.sqrt(1 + R[1][1] - R[0][0] - R[2][2]) * 2; w = (R[0][2] - R[2][0]) / s; x = (R[0][1] + R[1][0]) / s; y = 0.25 * s; z = (R[1][2] + R[2][1]) / s; }
  else { s = Math.sqrt(1 + R[2][2] - R[0][0] - R[1][1]) * 2; w = (R[1][0] - R[0][1]) / s; x = (R[0][2] + R[2][0]) / s; y = (R[1][2] + R[2][1]) / s; z = 0.25 * s; }
  const n = Math.hypot(x, y, z, w), q = [x / n, y / n, z / n, w / n];
  return q[3] >= 0 ? q : q.map((v) => -v);
}

// The rotation of q, operation for operation as sooc_quat_to_m3 (src/math/geom.c).
function rot(q) {
  const n = Math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const x = q[0] / n, y = q[1] / n, z = q[2] / n, w = q[3] / n;
  return [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
          [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
          [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]];
}

const DEFS = {
  "sensor_msgs/msg/Image": "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data\n",
  "sensor_msgs/msg/CameraInfo": "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 binning_y\nsensor_msgs/RegionOfInterest roi\n",
  "tf2_msgs/msg/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
};

async function main() {
  const args = process.argv.slice(2), fi = args.indexOf("--folder");
  const folder = fi >= 0 ? args.splice(fi, 2)[1] : null;
  const [seq, out, nArg] = args;
  if (!seq || !out) { console.log("usage: node write_mcap.mjs SEQ_DIR OUT.mcap [N] [--folder DIR]"); return 2; }
  if (folder) fs.mkdirSync(folder, { recursive: true });
  const colors = fs.readdirSync(seq).filter((f) => /^\d+-color\.png$/.test(f)).sort().slice(0, nArg ? +nArg : undefined);
  const fd = fs.openSync(out, "w");
  let pos = 0n;
  const writable = { position: () => pos, write: async (b) => { fs.writeSync(fd, b); pos += BigInt(b.length); } };
  const w = new McapWriter({ writable, chunkSize: 4 << 20 });
  await w.start({ profile: "ros2", library: "@mcap/core (sooc3d tests/logs/npm/write_mcap.mjs)" });
  const sc = {};
  for (const [name, def] of Object.entries(DEFS))
    sc[name] = await w.registerSchema({ name, encoding: "ros2msg", data: new TextEncoder().encode(def) });
  const ch = async (topic, type) => w.registerChannel({ topic, schemaId: sc[type], messageEncoding: "cdr", metadata: new Map() });
  const cTfs = await ch("/tf_static", "tf2_msgs/msg/TFMessage"), cTf = await ch("/tf", "tf2_msgs/msg/TFMessage");
  const cInfo = await ch("/camera/color/camera_info", "sensor_msgs/msg/CameraInfo");
  const cCol = await ch("/camera/color/image_raw", "sensor_msgs/msg/Image");
  const cDep = await ch("/camera/aligned_depth_to_color/image_raw", "sensor_msgs/msg/Image");
  const cam = "camera_color_optical_frame";
  let seqNo = 0;
  const put = (channelId, t, data) => w.addMessage({ channelId, sequence: seqNo++, logTime: t, publishTime: t, data });
  await put(cTfs, 0n, cdrTf([[0n, "map", "world", [0, 0, 0], [0, 0, 0, 1]]]));
  for (const name of colors) {
    const num = name.split("-")[0], t = BigInt(parseInt(num, 10)) * 33333333n, base = path.join(seq, num);
    const meta = readMat(`${base}-meta.mat`, ["intrinsic_matrix", "factor_depth", "rotation_translation_matrix"]);
    const Kc = meta.intrinsic_matrix.v, RTc = meta.rotation_translation_matrix.v, factor = meta.factor_depth.v[0];
    const K = [0, 1, 2].flatMap((r) => [0, 1, 2].map((c) => Kc[c * 3 + r]));   // column-major -> rows
    const R = [0, 1, 2].map((r) => [0, 1, 2].map((c) => RTc[c * 3 + r])), tcw = [0, 1, 2].map((r) => RTc[9 + r]);
    // camera-to-world: R^T, -R^T t
    const Rwc = [0, 1, 2].map((r) => [0, 1, 2].map((c) => R[c][r]));
    const twc = [0, 1, 2].map((r) => -(Rwc[r][0] * tcw[0] + Rwc[r][1] * tcw[1] + Rwc[r][2] * tcw[2]));
    const col = readPng(`${base}-color.png`), dep = readPng(`${base}-depth.png`);
    if (col.chans !== 3 || col.depth !== 8 || dep.chans !== 1 || dep.depth !== 16)
      throw new Error(`${base}: expected RGB8 colour and 16-bit grey depth`);
    const z = new Float32Array(dep.w * dep.h), inv = 1 / factor;
    for (let i = 0; i < z.length; i++) z[i] = dep.data.readUInt16BE(2 * i) * inv;
    const q = quat(Rwc);
    await put(cTf, t, cdrTf([[t, "world", cam, twc, q]]));
    if (folder) {
      const f6 = `frame-${String(parseInt(num, 10)).padStart(6, "0")}`;
      fs.symlinkSync(path.resolve(`${base}-color.png`), path.join(folder, `${f6}.color.png`));
      fs.symlinkSync(path.resolve(`${base}-depth.png`), path.join(folder, `${f6}.depth.png`));
      const Rq = rot(q);
      fs.writeFileSync(path.join(folder, `${f6}.pose.txt`),
                       [0, 1, 2].map((r) => `${Rq[r][0]} ${Rq[r][1]} ${Rq[r][2]} ${twc[r]}\n`).join("") + "0 0 0 1\n");
      if (!fs.existsSync(path.join(folder, "calib.yaml")))
        fs.writeFileSync(path.join(folder, "calib.yaml"),
                         `%YAML 1.2\n---\ncamera_name: ycb\nimage_width: ${col.w}\nimage_height: ${col.h}\n` +
                         `camera_matrix: {rows: 3, cols: 3, data: [${K.join(", ")}]}\n` +
                         `distortion_model: plumb_bob\ndistortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n` +
                         `depth_scale: ${1 / factor}\n`);
    }
    await put(cInfo, t, cdrCamInfo(t, cam, col.w, col.h, K));
    await put(cCol, t, cdrImage(t, cam, col.w, col.h, "rgb8", col.data));
    await put(cDep, t, cdrImage(t, cam, dep.w, dep.h, "32FC1", new Uint8Array(z.buffer)));
  }
  await w.end();
  fs.closeSync(fd);
  console.log(`write_mcap.mjs: ${colors.length} frames of ${seq} -> ${out} (@mcap/core, CDR, uncompressed chunks)`);
  return 0;
}

process.exit(await main());
