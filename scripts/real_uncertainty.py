#!/usr/bin/python3
"""How well the published position uncertainty of the shipped tabletop launch (launch/tabletop_geometric.yaml,
or the launch file in SOOC_LAUNCH, e.g. launch/labelfusion_replay.yaml for the learnt tabletop model) fits real
objects (docs/shm.md "The geometric map's fields").

The node maps YCB-Video 0000 (ground-truth object centres from its meta.mat, in the recording's frame) and the
label-fusion labels set (the median of each labelled object's points over all frames: the centre of its
visible surface), and 8 generated tabletop scenes (their scene.yaml; the support plane given, world.floor=0);
each labelled object is scored against the entry whose floor box holds its centre (else the nearest), per map
axis, in published sigmas (sqrt of cov_xx, cov_zz). Prints the rows and a JSON object as its last line.

  /usr/bin/python3 scripts/real_uncertainty.py        (from the repository root; SOOC_BIN, SOOC_SHARED_REAL,
                                                      SOOC_LAUNCH)

An object with no entry at all counts as missed (no error is scored for it).
"""
import json, os, glob, re, subprocess, tempfile
import numpy as np
import cv2

BIN = os.environ.get('SOOC_BIN', 'build/bin/sooc3d')
REAL = os.environ.get('SOOC_SHARED_REAL', '../shared/real')
TMP = tempfile.mkdtemp(prefix='sooc_unc_')
LAUNCH = os.environ.get('SOOC_LAUNCH', 'launch/tabletop_geometric.yaml')

def world_frame(db):
    out = subprocess.run(['sqlite3', db, "select value from meta where key='world_frame'"], capture_output=True, text=True).stdout.split()
    if len(out) < 18: return np.eye(4)
    v = list(map(float, out[2:18]))
    return np.array(v).reshape(4, 4)

def run(seq, tag, extra=()):
    db = f'{TMP}/{tag}.sqlite'
    for f in glob.glob(db + '*'): os.remove(f)
    subprocess.run([BIN, 'node', LAUNCH, '--set', f'sensor.path={seq}', '--set', f'shm.name=unc_{tag}',
                    '--set', 'shm.unlink_on_exit=true', '--set', f'map.db={db}', '--quiet', *extra], check=True,
                   stderr=subprocess.DEVNULL)
    subprocess.run([BIN, 'map', 'export', '--db', db, '--json', f'{TMP}/{tag}.json'], check=True, stderr=subprocess.DEVNULL)
    return json.load(open(f'{TMP}/{tag}.json'))['objects'], world_frame(db)

def ycb_gt():
    # inverse(rotation_translation_matrix) * poses[:, 3, k] of frame 1's meta.mat (as tests/table/test_table_source.c)
    return {8: [-0.087, 0.018, 0.032], 14: [0.003, 0.041, 0.031], 21: [0.015, -0.061, 0.036]}

def lf_gt(d):
    """centroid of every labelled point over all frames (the visible surface's centre), recording frame"""
    K = np.loadtxt(f'{d}/camera-intrinsics.color.txt')
    pts = {}
    for c in sorted(glob.glob(f'{d}/frame-*.color.png')):
        b = c[:-len('.color.png')]
        dep = cv2.imread(b + '.depth.png', cv2.IMREAD_UNCHANGED).astype(np.float64)
        dep = (dep.astype(np.uint16) >> 3) * 1e-4
        lab = cv2.imread(b + '.segm.png', cv2.IMREAD_UNCHANGED)
        if lab.ndim == 3: lab = lab[..., 0]
        T = np.loadtxt(b + '.pose.txt')
        v, u = np.nonzero((lab > 0) & (dep > 0.1))
        z = dep[v, u]
        p = np.stack([(u + 0.5 - K[0, 2]) / K[0, 0] * z, (v + 0.5 - K[1, 2]) / K[1, 1] * z, z, np.ones_like(z)])
        w = (T @ p)[:3].T
        for k in np.unique(lab[v, u]):
            pts.setdefault(int(k), []).append(w[lab[v, u] == k])
    return {k: np.median(np.concatenate(v), axis=0).tolist() for k, v in pts.items()}

def score(objs, Tws, gt, name):
    rows = []
    used = set()
    for k, c in gt.items():
        p = Tws @ np.array(c + [1.0])
        best, bd = None, 1e9
        for o in objs:
            d = np.hypot(o['x'] - p[0], o['z'] - p[2])
            # inside the footprint first
            cy, sy = np.cos(o['yaw']), np.sin(o['yaw'])
            dx, dz = p[0] - o['x'], p[2] - o['z']
            bx, bz = cy * dx - sy * dz, sy * dx + cy * dz
            inside = abs(bx) <= o['extent'][0] / 2 and abs(bz) <= o['extent'][2] / 2
            key = d - (10 if inside else 0)
            if key < bd: bd, best = key, o
        if best is None:
            continue   # no entry at all: missed
        used.add(best['id'])
        ex, ez = best['x'] - p[0], best['z'] - p[2]
        cov = best['cov_xz']
        rows.append((name, k, best['id'], ex, ez, ex / np.sqrt(cov[0]), ez / np.sqrt(cov[2]), best['presence']))
    un = [o['presence'] for o in objs if o['id'] not in used]
    return rows, [o['presence'] for o in objs if o['id'] in used], un

def mean(v):
    return float(np.mean(v)) if len(v) else None

allz = []
pm, pu = [], []
nent_r = nobj_r = 0
for seq, tag, gtf in [(f'{REAL}/ycb_video/data/0000', 'ycb', lambda: ycb_gt()),
                      (f'{REAL}/label_fusion/data/labels', 'lf', lambda: lf_gt(f'{REAL}/label_fusion/data/labels'))]:
    objs, T = run(seq, tag)
    gt = gtf()
    rows, m, u = score(objs, T, gt, tag)
    pm += m; pu += u
    nent_r += len(objs); nobj_r += len(gt)
    print(f'{tag}: {len(objs)} entries for {len(gt)} objects ({len(gt) - len(rows)} without an entry); presence of '
          f'the matched entries {mean(m) or float("nan"):.3f}, of the others {mean(u) or float("nan"):.3f} ({len(u)})')
    for r in rows:
        print('  %s obj %d -> entry %d: err x %.3f z %.3f m = %.2f / %.2f sigma, presence %.3f' % r)
        allz += [r[5], r[6]]
z = np.abs(np.array(allz))
real = {'launch': LAUNCH, 'objects': nobj_r, 'entries': nent_r, 'n_axis_errors': len(z), 'within_1sigma': mean(z <= 1),
        'within_2sigma': mean(z <= 2), 'presence_matched': mean(pm), 'presence_unmatched': mean(pu)}

# generated tabletop scenes: the scene's own object centres
gz = []
subprocess.run([BIN, 'gen', '--preset', 'tabletop', '--no-sheet', '--scale', 's', '--scenes', '8', '--seed', '41', '--out', f'{TMP}/gen'],
               check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
nent = nobj = 0
gpm, gpu = [], []
for d in sorted(glob.glob(f'{TMP}/gen/scene_*')):
    y = open(d + '/scene.yaml').read()
    gt = {int(m[0]): [float(m[1]), float(m[4]) / 2, float(m[2])] for m in
          re.findall(r"\{id: (\d+), shape: \w+, x: ([-\d.e]+), z: ([-\d.e]+), yaw: [-\d.e]+, size: \[([-\d.e]+), ([-\d.e]+)", y)}
    objs, T = run(d, 'g' + d[-2:], ('--set', 'world.floor=0', '--set', 'world.up=+y'))
    rows, m, u = score(objs, T, gt, 'gen')
    gpm += m; gpu += u
    nent += len(objs); nobj += len(gt)
    gz += [r[5] for r in rows] + [r[6] for r in rows]
z = np.abs(np.array(gz))
gen = {'scenes': 8, 'objects': nobj, 'entries': nent, 'n_axis_errors': len(z), 'within_1sigma': mean(z <= 1),
       'within_2sigma': mean(z <= 2), 'presence_matched': mean(gpm), 'presence_unmatched': mean(gpu)}
print(json.dumps({'real': real, 'generated': gen}))
subprocess.run(['rm', '-rf', TMP])
