"""sooc3d_table: read a sooc3d shared-memory object table from Python (standard library only).

    import sooc3d_table
    t = sooc3d_table.Table("my_table")            # /dev/shm/sooc3d.v1.my_table, read-only
    epoch, records, n_objects, stamp_ns = t.snapshot()
    p, R = sooc3d_table.pose_source(t.t_src_map, records[0])     # in the robot base's frame
    k = sooc3d_table.pick(records, T_map_cam, fx, fy, cx, cy, u, v)   # which object is at a pixel

The layout and the seqlock protocol are docs/shm.md's (ABI v1); the C API is
include/sooc3d/table.h. Each record is a dict: object_id, flags, obs_count,
presence, x, y, z, yaw, cov_xzyaw, extent, first_seen_ns, last_seen_ns.

Memory-order note: the table-level seqlock copy (load table_seq, copy the
records with one memcpy, load table_seq again) is correct on x86-64, whose
loads are not reordered with each other. On weakly ordered CPUs (ARM) prefer
the C API (sooc_table_snapshot, e.g. through ctypes), which uses fences.
"""
import fcntl
import math
import mmap
import os
import re
import struct
import sys
import time

# ---- ABI v1 (include/sooc3d/table.h; offsets are frozen) --------------------
SCHEMA_STRING = (
    "sooc3d.table.v1;"
    "header 4096:magic u64 0,abi_major u16 8,abi_minor u16 10,header_size u32 12,"
    "record_size u32 16,capacity u32 20,records_offset u64 24,schema_hash u64 32,"
    "frame_id char[32] 40,latent_max u32 72,reserved_a u32 76,instance_id u64 80,"
    "writer_pid i64 88,hflags u64 96,table_seq u64 104,heartbeat_mono_ns i64 112,"
    "high_water u64 120,n_objects u64 128,created_real_ns i64 136,latent_dim u32 256,"
    "reserved_b u32 260,latent_model_id u64 264,stamp_ns i64 272,T_src_map f64[16] 280;"
    "record 256:seq u64 0,object_id u64 8,flags u32 16,obs_count u32 20,presence f32 24,"
    "x f32 28,z f32 32,yaw f32 36,cov_xzyaw f32[6] 40,y f32 64,extent f32[3] 68,"
    "first_seen_ns i64 80,last_seen_ns i64 88,latent_dim u32 96,reserved0 u32 100,"
    "reserved u8[24] 104,latent f32[32] 128")
SCHEMA_HASH = 0x784F569FFDA8B30A
MAGIC = 0x42544433434F4F53  # "SOOC3DTB"
ABI_MAJOR = 1
HEADER_SIZE, RECORD_SIZE = 4096, 256
OFF_MAGIC, OFF_ABI_MAJOR, OFF_HEADER_SIZE, OFF_RECORD_SIZE, OFF_CAPACITY = 0, 8, 12, 16, 20
OFF_RECORDS_OFFSET, OFF_SCHEMA_HASH, OFF_FRAME_ID = 24, 32, 40
OFF_INSTANCE_ID, OFF_WRITER_PID, OFF_HFLAGS, OFF_TABLE_SEQ = 80, 88, 96, 104
OFF_HEARTBEAT, OFF_HIGH_WATER, OFF_N_OBJECTS = 112, 120, 128
OFF_STAMP_NS, OFF_T_SRC_MAP = 272, 280
OFF_ABI_MINOR, OFF_STORE_SEQ, OFF_STORE = 10, 144, 152  # store block: abi_minor >= 1
STORE_STATES = {0: "none", 1: "ok", 2: "failing"}
STORE_FAULTS = {0: "", 1: "disk full", 2: "I/O error", 3: "locked", 4: "corrupt", 5: "out of memory", 6: "other"}
FLAG_VALID, FLAG_TENTATIVE, FLAG_REMOVED, FLAG_STATIC = 1, 2, 4, 8
FLAG_SYMMETRIC = 0x10
# the box's quality (abi_minor >= 2): tight box of its own geometry, cut at the locality box, empty, faint
FLAG_BOX_TIGHT, FLAG_BOX_CLIPPED, FLAG_BOX_EMPTY, FLAG_BOX_FAINT = 0x20, 0x40, 0x80, 0x100
HFLAG_WRITER_EXITED = 1
READ_RETRIES = 100
BUSY_MAX_S = 2.0  # a live writer inside one batch for longer: report "busy"
HEARTBEAT_STALE_NS = 1_000_000_000
# record: seq, object_id, flags, obs_count, presence, x, z, yaw, cov[6], y,
#         extent[3], first_seen_ns, last_seen_ns, latent_dim, reserved0, 24 pad, latent[32]
RECORD = struct.Struct("<QQIIffff6ff3fqqII24x32f")
assert RECORD.size == RECORD_SIZE


def fnv1a64(text):
    h = 0xCBF29CE484222325
    for b in text.encode():
        h = ((h ^ b) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


class TableError(Exception):
    pass


class Table:
    """Read-only view of one table. Word loads use the native 'Q' format, which
    CPython copies with a single 8-byte memcpy (one aligned load)."""

    def __init__(self, name):
        if not re.fullmatch(r"[A-Za-z0-9_-][A-Za-z0-9_.-]{0,63}", name):
            raise TableError("invalid table name %r" % name)
        if sys.byteorder != "little":
            raise TableError("the table ABI is little-endian")
        self.path = "/dev/shm/sooc3d.v1." + name
        self.fd = os.open(self.path, os.O_RDONLY)  # FileNotFoundError if absent
        try:
            size = os.fstat(self.fd).st_size
            if size < HEADER_SIZE:
                raise TableError("table not ready")
            self.mm = mmap.mmap(self.fd, size, mmap.MAP_SHARED, mmap.PROT_READ)
            self._check(size)
        except Exception:
            os.close(self.fd)
            raise

    def u64(self, off):
        return struct.unpack_from("=Q", self.mm, off)[0]

    def i64(self, off):
        return struct.unpack_from("=q", self.mm, off)[0]

    def _check(self, size):
        if self.u64(OFF_MAGIC) != MAGIC:
            raise TableError("table not ready (no magic)")
        abi_major, = struct.unpack_from("<H", self.mm, OFF_ABI_MAJOR)
        hs, rs, cap = struct.unpack_from("<III", self.mm, OFF_HEADER_SIZE)
        roff, shash = struct.unpack_from("<QQ", self.mm, OFF_RECORDS_OFFSET)
        if fnv1a64(SCHEMA_STRING) != SCHEMA_HASH:
            raise TableError("this script's schema string and hash disagree")
        if (abi_major != ABI_MAJOR or hs != HEADER_SIZE or rs != RECORD_SIZE
                or shash != SCHEMA_HASH or roff != HEADER_SIZE or cap == 0
                or roff + cap * rs > size):
            raise TableError("incompatible table (ABI %d, schema %016x)" % (abi_major, shash))
        self.capacity = cap
        self.frame_id = self.mm[OFF_FRAME_ID:OFF_FRAME_ID + 32].split(b"\0")[0].decode()

    def snapshot(self):
        """(epoch, [record dicts]) copied between two equal even table_seq loads."""
        for attempt in range(READ_RETRIES):
            s0 = self.u64(OFF_TABLE_SEQ)
            if s0 & 1:
                time.sleep(0.0002 if attempt >= 8 else 0)
                continue
            hw = min(self.u64(OFF_HIGH_WATER), self.capacity)
            data = self.mm[HEADER_SIZE:HEADER_SIZE + hw * RECORD_SIZE]  # one memcpy
            n_objects = self.u64(OFF_N_OBJECTS)
            stamp_ns = self.i64(OFF_STAMP_NS)
            self.t_src_map = struct.unpack_from("<16d", self.mm, OFF_T_SRC_MAP)
            if self.u64(OFF_TABLE_SEQ) != s0:
                continue
            recs = []
            for t in RECORD.iter_unpack(data):
                if t[1] == 0:
                    continue  # empty slot
                recs.append(dict(object_id=t[1], flags=t[2], obs_count=t[3], presence=t[4],
                                 x=t[5], z=t[6], yaw=t[7], cov_xzyaw=t[8:14], y=t[14],
                                 extent=t[15:18], first_seen_ns=t[18], last_seen_ns=t[19]))
            return s0 // 2, recs, n_objects, stamp_ns
        raise TableError("table busy (seqlock retries exhausted)")

    def store(self):
        """The map database's state (the header's store block, abi_minor >= 1), copied under
        store_seq: dict(state, fault, pending, pending_kf, committed_ns); state "none" for an
        older writer or a node without a database."""
        abi_minor, = struct.unpack_from("<H", self.mm, OFF_ABI_MINOR)
        if abi_minor < 1:
            return dict(state="none", fault="", pending=0, pending_kf=0, committed_ns=None)
        for attempt in range(READ_RETRIES):
            s0 = self.u64(OFF_STORE_SEQ)
            if s0 & 1:
                time.sleep(0.0002 if attempt >= 8 else 0)
                continue
            state, fault, pending, pending_kf, committed = struct.unpack_from("<IIQQq", self.mm, OFF_STORE)
            if self.u64(OFF_STORE_SEQ) != s0:
                continue
            return dict(state=STORE_STATES.get(state, "?"), fault=STORE_FAULTS.get(fault, "other"),
                        pending=pending, pending_kf=pending_kf,
                        committed_ns=None if committed == -(1 << 63) else committed)
        raise TableError("table busy (store block retries exhausted)")

    def writer_pid(self):
        return self.i64(OFF_WRITER_PID)

    def writer_alive(self):
        """(alive, reason): flock probe + WRITER_EXITED + heartbeat age."""
        if self.u64(OFF_HFLAGS) & HFLAG_WRITER_EXITED:
            return False, "closed cleanly"
        try:
            fcntl.flock(self.fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
            fcntl.flock(self.fd, fcntl.LOCK_UN)
            return False, "process died"
        except BlockingIOError:
            pass
        age = time.clock_gettime_ns(time.CLOCK_MONOTONIC) - self.i64(OFF_HEARTBEAT)
        if age >= HEARTBEAT_STALE_NS:
            return False, "heartbeat stale"
        return True, "alive"

    def close(self):
        self.mm.close()
        os.close(self.fd)


def pose_source(T, r):
    """A record's box centre and box axes (rows of R: the source's x, y, z; columns: the box's) in the
    pose source's frame (the robot base, the recording's world): T = the header's T_src_map, row-major.
    The same as sooc_table_pose_source() in table.h."""
    m = (r["x"], r["y"], r["z"])
    p = [T[4 * i] * m[0] + T[4 * i + 1] * m[1] + T[4 * i + 2] * m[2] + T[4 * i + 3] for i in range(3)]
    c, s = math.cos(r["yaw"]), math.sin(r["yaw"])
    ry = (c, 0, s, 0, 1, 0, -s, 0, c)
    R = [T[4 * i] * ry[j] + T[4 * i + 1] * ry[3 + j] + T[4 * i + 2] * ry[6 + j] for i in range(3) for j in range(3)]
    return p, R


def pick(records, T_map_cam, fx, fy, cx, cy, u, v):
    """Which object is at pixel (u, v) of a pinhole camera at T_map_cam (camera to map, row-major 16):
    (index into records, distance along the ray) of the nearest valid box the ray enters, or (-1, None).
    The same as sooc_table_pick() in table.h."""
    T = T_map_cam
    dc = ((u - cx) / fx, (v - cy) / fy, 1.0)
    o = (T[3], T[7], T[11])
    d = [T[4 * i] * dc[0] + T[4 * i + 1] * dc[1] + T[4 * i + 2] * dc[2] for i in range(3)]
    best, bt = -1, math.inf
    for k, r in enumerate(records):
        if not r["object_id"] or not (r["flags"] & FLAG_VALID) or (r["flags"] & FLAG_REMOVED):
            continue
        c, s = math.cos(r["yaw"]), math.sin(r["yaw"])
        po = (o[0] - r["x"], o[1] - r["y"], o[2] - r["z"])
        ob = (c * po[0] - s * po[2], po[1], s * po[0] + c * po[2])
        db = (c * d[0] - s * d[2], d[1], s * d[0] + c * d[2])
        t0, t1, miss = 0.0, math.inf, False
        for a in range(3):
            h = 0.5 * r["extent"][a]
            if abs(db[a]) < 1e-15:
                miss = abs(ob[a]) > h
            else:
                ta, tb = sorted(((-h - ob[a]) / db[a], (h - ob[a]) / db[a]))
                t0, t1 = max(t0, ta), min(t1, tb)
                miss = t0 > t1
            if miss:
                break
        if not miss and t0 < bt:
            best, bt = k, t0
    return (best, bt) if best >= 0 else (-1, None)
