#!/usr/bin/python3
"""Follow a sooc3d object table live from Python (standard library only).

    python3 scripts/planner_example.py <name> [--once] [--wait S] [--interval MS] [--rep103 | --source]

Reads /dev/shm/sooc3d.v1.<name> directly with mmap and the seqlock protocol of
docs/shm.md (no compiled extension, no sooc3d library). Prints the table
whenever its epoch changes: id, flags, x, z, yaw (deg), presence, observations,
age. Exit status: 0 when the writer closed cleanly, on Ctrl-C or after --once
printed a snapshot; 1 if the table cannot be opened; 3 when the writer died or
hung, or the table stays busy (left mid-batch by a writer killed inside a
keyframe, or inside one batch for more than 2 s), with a message on stderr.

Memory-order note: the table-level seqlock copy below (load table_seq, copy
the records with one memcpy, load table_seq again) is correct on x86-64, whose
loads are not reordered with each other. On weakly ordered CPUs (ARM) prefer
the C API (sooc_table_snapshot, e.g. through ctypes), which uses fences.
"""
import argparse
import fcntl
import math
import mmap
import os
import re
import signal
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
FLAG_VALID, FLAG_TENTATIVE, FLAG_REMOVED, FLAG_STATIC = 1, 2, 4, 8
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


def print_table(epoch, recs, n_objects, stamp_ns, frame_id, rep103, T_src_map=None):
    ref = stamp_ns if stamp_ns else time.time_ns()
    print("epoch %d  objects %d  frame %s" % (epoch, n_objects,
                                              "pose source (T_src_map)" if T_src_map else frame_id))
    print("  %10s %4s %9s %9s %9s %8s %8s %5s %8s %8s %17s" % (
        "id", "flag", "x_ros" if rep103 else "x", "y_ros" if rep103 else "y", "z_ros" if rep103 else "z",
        "yaw_deg", "presence", "obs", "age_s", "sigma_m", "box x*y*z (m)"))
    for r in recs:
        fl = "".join(c if r["flags"] & b else "-" for c, b in
                     (("V", FLAG_VALID), ("T", FLAG_TENTATIVE), ("R", FLAG_REMOVED),
                      ("S", FLAG_STATIC)))
        p, yaw = (r["x"], r["y"], r["z"]), r["yaw"]
        if T_src_map:  # the box centre in the pose source's frame; yaw: its x axis about the source's
            # axis nearest to the map's up (+z for a z-up robot base, +y for a y-up world)
            p, R = pose_source(T_src_map, r)
            T = T_src_map
            if abs(T[9]) >= abs(T[5]):
                yaw = math.copysign(1, T[9]) * math.atan2(R[3], R[0])
            else:
                yaw = math.copysign(1, T[5]) * math.atan2(-R[6], R[0])
        elif rep103:  # x_ros = -z_map, y_ros = -x_map, z_ros = y_map, yaw unchanged
            p = (-r["z"], -r["x"], r["y"])
        age = (ref - r["last_seen_ns"]) * 1e-9 if r["last_seen_ns"] else 0.0
        c = r["cov_xzyaw"]
        sig = math.sqrt(max(0.0, 0.5 * (c[0] + c[3])))
        e = r["extent"]
        print("  %10d %4s %9.3f %9.3f %9.3f %8.1f %8.3f %5d %8.2f %8.4f %5.3fx%5.3fx%5.3f" % (
            r["object_id"], fl, p[0], p[1], p[2], yaw * 57.29577951308232, r["presence"],
            r["obs_count"], age, sig, e[0], e[1], e[2]))
    sys.stdout.flush()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("name", help="table name (the node's shm name)")
    ap.add_argument("--once", action="store_true", help="print one snapshot and exit")
    ap.add_argument("--wait", type=float, default=0.0, help="seconds to wait for the table")
    ap.add_argument("--interval", type=float, default=100.0, help="polling period in ms")
    ap.add_argument("--rep103", action="store_true", help="print poses in a ROS REP-103 frame of the map")
    ap.add_argument("--source", action="store_true",
                    help="print poses in the pose source's frame (the robot base): T_src_map applied")
    args = ap.parse_args()
    stop = []
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))

    deadline = time.monotonic() + args.wait
    while True:
        try:
            table = Table(args.name)
            break
        except (FileNotFoundError, TableError) as e:
            retry = isinstance(e, FileNotFoundError) or "not ready" in str(e)
            if not retry or time.monotonic() >= deadline or stop:
                print("planner_example.py: cannot open table %r: %s" % (args.name, e),
                      file=sys.stderr)
                return 1
            time.sleep(0.1)
    last = None
    busy_since = None  # monotonic time of the first busy snapshot in a row
    status = 0
    try:
        while not stop:
            busy = False
            try:
                epoch, recs, n_obj, stamp = table.snapshot()
                if epoch != last or args.once:
                    print_table(epoch, recs, n_obj, stamp, table.frame_id, args.rep103,
                                table.t_src_map if args.source else None)
                    last = epoch
                if args.once:
                    break
            except TableError:
                busy = True  # try again next period, unless the writer is gone
            busy_since = (busy_since or time.monotonic()) if busy else None
            alive, why = table.writer_alive()
            if not alive:
                if busy:
                    print("planner_example.py: table %r is stuck mid-batch: its writer (pid %d) "
                          "%s inside a batch; no consistent copy can be read until a new writer "
                          "takes the table over" % (args.name, table.writer_pid(),
                                                    {"closed cleanly": "closed",
                                                     "heartbeat stale": "hung",
                                                     "process died": "died"}[why]),
                          file=sys.stderr)
                    status = 3
                    break
                print("writer gone (%s)" % why)
                if why != "closed cleanly":
                    print("planner_example.py: table %r: writer (pid %d) %s" % (
                        args.name, table.writer_pid(),
                        "died" if why == "process died" else "hung (heartbeat stale)"),
                        file=sys.stderr)
                    status = 3
                break
            if busy_since is not None and time.monotonic() - busy_since > BUSY_MAX_S:
                print("planner_example.py: table %r busy: its writer (pid %d) is alive but has "
                      "been inside one batch for more than %.0f s" % (
                          args.name, table.writer_pid(), BUSY_MAX_S), file=sys.stderr)
                status = 3
                break
            time.sleep(args.interval / 1000.0)
    finally:
        table.close()
    return status


if __name__ == "__main__":
    sys.exit(main())
