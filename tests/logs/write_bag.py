#!/usr/bin/python3
"""Write frames of a 7-Scenes folder as a ROS 1 bag with Debian's python3-rosbag.

usage: write_bag.py SEQ_DIR OUT.bag N [--compression lz4|bz2|none] [--folder DIR]

The messages are serialised here with struct (ROS 1 serialisation, written
independently of sooc3d's encoders), then recorded with rosbag.Bag.write(raw=True):
  /camera/color/image_raw/compressed  sensor_msgs/CompressedImage  the JPEG bytes as shipped
  /camera/color/camera_info           sensor_msgs/CameraInfo       K from camera-intrinsics.txt
  /camera/depth/image_rect_raw        sensor_msgs/Image            16UC1 millimetres (the PNG's samples)
  /camera/depth/camera_info           sensor_msgs/CameraInfo       the same K (depth registered to colour)
  /tf                                 tf2_msgs/TFMessage           odom -> camera_color_optical_frame
  /tf_static                          tf2_msgs/TFMessage           map -> odom (identity)
Stamps are the folder reader's: frame number x 33333333 ns. With --folder DIR
the same frames are also written as a 7-Scenes folder (links to the images,
camera-intrinsics.txt, and pose files holding the rotation the bag's
quaternion stands for, computed as sooc_quat_to_m3 does), so that folder and
bag hold the same frames: a recorded rotation matrix that is not exactly
orthonormal cannot survive a quaternion. Exits 77 when python3-rosbag, numpy
or OpenCV (cv2) is missing.
"""
import glob
import os
import struct
import sys

try:
    import cv2
    import numpy as np
    import rosbag
    import genpy
except ImportError as e:  # the test prints this and skips
    print("write_bag.py: SKIP: %s (python3-rosbag, python3-numpy, python3-opencv)" % e)
    sys.exit(77)

MD5 = {
    "sensor_msgs/Image": "060021388200f6f0f447d0fcd9c64743",
    "sensor_msgs/CompressedImage": "8f7a12909da2c9d3332d540a0977563f",
    "sensor_msgs/CameraInfo": "c9a58c1b0b154e0e6da7578cb991d214",
    "tf2_msgs/TFMessage": "94810edda583a504dfda3829e70d7eec",
}
COLOR_FRAME = "camera_color_optical_frame"


def s_str(s):
    b = s.encode()
    return struct.pack("<I", len(b)) + b


def s_header(stamp_ns, frame_id):
    return struct.pack("<III", 0, stamp_ns // 1000000000, stamp_ns % 1000000000) + s_str(frame_id)


def s_caminfo(stamp_ns, frame_id, w, h, K):
    P = [K[0], K[1], K[2], 0.0, K[3], K[4], K[5], 0.0, K[6], K[7], K[8], 0.0]
    return (s_header(stamp_ns, frame_id) + struct.pack("<II", h, w) + s_str("plumb_bob") +
            struct.pack("<I5d", 5, 0, 0, 0, 0, 0) + struct.pack("<9d", *K) +
            struct.pack("<9d", 1, 0, 0, 0, 1, 0, 0, 0, 1) + struct.pack("<12d", *P) +
            struct.pack("<IIIIIIB", 0, 0, 0, 0, 0, 0, 0))


def s_image(stamp_ns, frame_id, img, encoding):
    h, w = img.shape[:2]
    data = np.ascontiguousarray(img).tobytes()
    step = len(data) // h
    return (s_header(stamp_ns, frame_id) + struct.pack("<II", h, w) + s_str(encoding) +
            struct.pack("<BI", 0, step) + struct.pack("<I", len(data)) + data)


def s_cimage(stamp_ns, frame_id, fmt, data):
    return s_header(stamp_ns, frame_id) + s_str(fmt) + struct.pack("<I", len(data)) + data


def s_tf(items):
    out = struct.pack("<I", len(items))
    for stamp_ns, parent, child, t, q in items:
        out += s_header(stamp_ns, parent) + s_str(child) + struct.pack("<3d", *t) + struct.pack("<4d", *q)
    return out


def quat(R):
    """Rotation matrix -> (x, y, z, w), w >= 0."""
    tr = R[0][0] + R[1][1] + R[2][2]
    if tr > 0:
        s = (tr + 1.0) ** 0.5 * 2
        w, x, y, z = 0.25 * s, (R[2][1] - R[1][2]) / s, (R[0][2] - R[2][0]) / s, (R[1][0] - R[0][1]) / s
    elif R[0][0] > R[1][1] and R[0][0] > R[2][2]:
        s = (1.0 + R[0][0] - R[1][1] - R[2][2]) ** 0.5 * 2
        w, x, y, z = (R[2][1] - R[1][2]) / s, 0.25 * s, (R[0][1] + R[1][0]) / s, (R[0][2] + R[2][0]) / s
    elif R[1][1] > R[2][2]:
        s = (1.0 + R[1][1] - R[0][0] - R[2][2]) ** 0.5 * 2
        w, x, y, z = (R[0][2] - R[2][0]) / s, (R[0][1] + R[1][0]) / s, 0.25 * s, (R[1][2] + R[2][1]) / s
    else:
        s = (1.0 + R[2][2] - R[0][0] - R[1][1]) ** 0.5 * 2
        w, x, y, z = (R[1][0] - R[0][1]) / s, (R[0][2] + R[2][0]) / s, (R[1][2] + R[2][1]) / s, 0.25 * s
    n = (x * x + y * y + z * z + w * w) ** 0.5
    q = [x / n, y / n, z / n, w / n]
    return q if q[3] >= 0 else [-v for v in q]


def rot(q):
    """The rotation of q, operation for operation as sooc_quat_to_m3 (src/math/geom.c)."""
    n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]) ** 0.5
    x, y, z, w = q[0] / n, q[1] / n, q[2] / n, q[3] / n
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]


class _Type:
    """What rosbag.Bag.write(raw=True) wants of a message class."""

    def __init__(self, name):
        self._type = name
        self._md5sum = MD5[name]
        self._full_text = ""


def main():
    if len(sys.argv) < 4:
        print(__doc__)
        return 2
    seq, out, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
    comp = "lz4"
    if "--compression" in sys.argv:
        comp = sys.argv[sys.argv.index("--compression") + 1]
    folder = sys.argv[sys.argv.index("--folder") + 1] if "--folder" in sys.argv else None
    with open(os.path.join(seq, "camera-intrinsics.txt")) as f:
        K = [float(v) for v in f.read().split()]
    colors = sorted(glob.glob(os.path.join(seq, "frame-*.color.jpg")))[:n]
    if folder:
        os.makedirs(folder, exist_ok=True)
        with open(os.path.join(folder, "camera-intrinsics.txt"), "w") as f:
            f.write("%r %r %r\n%r %r %r\n%r %r %r\n" % tuple(K))
    types = {k: _Type(k) for k in MD5}

    def put(bag, topic, typ, data, stamp_ns):
        hdr = {"topic": topic, "type": typ, "md5sum": MD5[typ], "message_definition": ""}
        bag.write(topic, (typ, data, MD5[typ], types[typ]), genpy.Time(stamp_ns // 1000000000, stamp_ns % 1000000000),
                  raw=True, connection_header=hdr)

    with rosbag.Bag(out, "w", compression=comp) as bag:
        first = True
        for cpath in colors:
            number = int(os.path.basename(cpath).split("-")[1].split(".")[0])
            t = number * 33333333
            base = cpath[:-len(".color.jpg")]
            depth = cv2.imread(base + ".depth.png", cv2.IMREAD_UNCHANGED)
            if depth is None or depth.dtype != np.uint16:
                print("write_bag.py: %s.depth.png is not a 16-bit PNG" % base)
                return 1
            h, w = depth.shape
            with open(base + ".pose.txt") as f:
                T = [[float(v) for v in line.split()] for line in f if line.strip()]
            R = [row[:3] for row in T[:3]]
            tr = [T[0][3], T[1][3], T[2][3]]
            if first:
                put(bag, "/tf_static", "tf2_msgs/TFMessage", s_tf([(t, "map", "odom", [0, 0, 0], [0, 0, 0, 1])]), t)
                first = False
            q = quat(R)
            put(bag, "/tf", "tf2_msgs/TFMessage", s_tf([(t, "odom", COLOR_FRAME, tr, q)]), t)
            if folder:
                name = os.path.basename(base)
                for ext in (".color.jpg", ".depth.png"):
                    dst = os.path.join(folder, name + ext)
                    if not os.path.exists(dst):
                        os.symlink(os.path.abspath(base + ext), dst)
                Rq = rot(q)
                with open(os.path.join(folder, name + ".pose.txt"), "w") as f:
                    for r in range(3):
                        f.write("%r %r %r %r\n" % (Rq[r][0], Rq[r][1], Rq[r][2], tr[r]))
                    f.write("0 0 0 1\n")
            put(bag, "/camera/color/camera_info", "sensor_msgs/CameraInfo", s_caminfo(t, COLOR_FRAME, w, h, K), t)
            with open(cpath, "rb") as f:
                put(bag, "/camera/color/image_raw/compressed", "sensor_msgs/CompressedImage",
                    s_cimage(t, COLOR_FRAME, "jpeg", f.read()), t)
            put(bag, "/camera/depth/camera_info", "sensor_msgs/CameraInfo", s_caminfo(t, COLOR_FRAME, w, h, K), t)
            put(bag, "/camera/depth/image_rect_raw", "sensor_msgs/Image", s_image(t, COLOR_FRAME, depth, "16UC1"), t)
    print("write_bag.py: %d frames of %s -> %s (%s chunks)" % (len(colors), seq, out, comp))
    return 0


if __name__ == "__main__":
    sys.exit(main())
