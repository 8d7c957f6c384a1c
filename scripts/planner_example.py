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
import math
import os
import signal
import sys
import time

try:  # installed (cmake --install: the table component) on the interpreter's path
    import sooc3d_table
except ImportError:  # next to this script: the repository's python/, or PREFIX/lib/python3.N/dist-packages
    _here = os.path.dirname(os.path.abspath(__file__))
    sys.path[:0] = [os.path.join(_here, "..", "python"),
                    os.path.join(_here, "..", "..", "lib", "python%d.%d" % sys.version_info[:2], "dist-packages")]
    import sooc3d_table
from sooc3d_table import (BUSY_MAX_S, FLAG_REMOVED, FLAG_STATIC, FLAG_TENTATIVE, FLAG_VALID, Table,
                          TableError, pose_source)


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
                    st = table.store()
                    if st["state"] == "failing":
                        print("  map database failing%s: %d objects and %d keyframes not stored yet" % (
                            " (%s)" % st["fault"] if st["fault"] else "", st["pending"], st["pending_kf"]))
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
