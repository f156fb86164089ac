#!/usr/bin/env python3
"""Convert the ViSP "rbt" RGB-D sequence (lagadic/visp-images, folder rbt/) into
splattrack sequence directories (see docs/formats.md).

Usage
-----
    scripts/get_real_data.sh [OUT_DIR]                            # fetches and converts
    python3 convert_visp.py /path/to/visp-images/.git            # or a bare mirror
    python3 convert_visp.py GITDIR --out DATA_DIR --commit HEAD --jobs 2
    python3 convert_visp.py GITDIR --gt apriltag                  # skip GT refinement (fast)
    python3 convert_visp.py GITDIR --check /tmp/datacheck         # also write overlay PNGs

GITDIR is a git directory (bare mirror or a clone's .git) of
https://github.com/lagadic/visp-images. Nothing is written outside --out (and
--check). Requires python3 with numpy, scipy, pillow and trimesh; git on PATH.
Runtime: ~40 min on 2 CPU cores with the default GT refinement, ~3 min
with --gt apriltag. Deterministic (fixed sampling seeds).

What it produces (for each object: cube, dragon)
------------------------------------------------
    <out>/visp_rbt_<obj>/camera.json        pinhole intrinsics (no distortion)
    <out>/visp_rbt_<obj>/frames/NNNNNN.png  the 99 colour frames (lossless PNG;
                                            the dragon sequence is a fixed crop)
    <out>/visp_rbt_<obj>/poses.csv          ground truth, one row per frame
    <out>/visp_rbt_<obj>/init.csv           ground truth of frame 0
    <out>/visp_rbt_<obj>/poses_apriltag.csv the unrefined AprilTag-grid GT
    <out>/visp_rbt_<obj>/gt_quality.csv     per-frame sharpness / edge-fit numbers, gt_ok flag
    <out>/visp_rbt_<obj>/conversion_info.json  crop, keyframes, colour-bake frames, commit
    <out>/visp_rbt_<obj>/model.ply          surface samples with normals, colours, radii
    <out>/visp_rbt_<obj>/mesh.obj (+ .mtl)  the original mesh, untouched
    <out>/visp_rbt_<obj>/keyframes/         3 frames + keyframes/poses.csv

Conventions
-----------
All poses are object-to-camera, X_cam = R X_obj + t, metres, OpenCV camera
(x right, y down, z forward, pixel (0,0) = centre of the top-left pixel), which is
also ViSP's convention for cMo. The object frame is the frame of the ORIGINAL
.obj file. ViSP's render-based tracker loads .obj files through Panda3D, which
converts them from Y-up to Z-up, so ViSP's object frame is
    X_visp = A X_obj,  A = [[1,0,0],[0,0,-1],[0,1,0]]
(verified: the 4 landmark points of rbt/models/dragon/dragon.init lie within
0.35 mm of the .obj surface only under this mapping). Hence every ViSP cMo is
converted as  T_obj = cMo_visp @ A  (A as a 4x4).

Ground truth
------------
The sequence has no per-object GT; ViSP's own test (modules/rbt/test/
catchRBTDataset.cpp) builds it from the pose of an AprilTag board seen in every
frame, cMg(i) (apriltag_data.json, "grid"), and a fixed board-to-object
transform:  cMo(i) = cMg(i) gMo,  gMo = cMg(0)^-1 cMo_init  (init/<obj>.json,
a tracker pose at frame 0). That is written to poses_apriltag.csv. Because the
board is ~1 m away and the objects ~0.5 m, the board-only camera pose is
extrapolated to the objects: its covariance alone gives 1-5 px (1 sigma) there,
and measured against the image its object outlines are off by 5-10 px in most
frames and by up to 30-40 px in fast-motion frames (rolling shutter). --gt refined (default) therefore re-estimates, per frame,
the camera pose from (a) the AprilTag corners (board layout measured from the
per-tag poses), jointly with (b) the silhouettes of BOTH the cube and the
dragon (model contour points matched to the strongest colour edge along the
contour normal, Tukey IRLS, coarse-to-fine search radius), and re-estimates
each object's fixed board-to-object transform gMo from all frames; 3 rounds.
The result is written to poses.csv.
Details: round 1 goes through the frames in order and starts each frame from two
candidates (the raw board pose, and the board pose corrected by the previous
frame's correction), search radius 16 -> 3 px; the candidate whose silhouettes fit
better wins. The corners enter with a Huber weight (sigma 2 px) so that they can
never drop out: the dragon's silhouette alone does not pin the camera rotation.
gt_quality.csv flags (gt_ok=0) the frames where, after refinement, the silhouette
of either object still misses the image edges (median offset > 1.6 px or fewer than
40 % of contour points within 1.5 px): these are fast-motion frames with blur and
rolling-shutter distortion, where no single rigid pose fits; their GT is doubtful.
"""
import argparse, io, json, os, subprocess, sys, time
from multiprocessing import Pool

import numpy as np
from PIL import Image
from scipy.ndimage import gaussian_filter, map_coordinates, binary_closing, binary_erosion
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation as Rot
import trimesh

A4 = np.eye(4)
A4[:3, :3] = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)
OBJECTS = ['cube', 'dragon']
SEQ = 'rbt/sequence/'
MOD = 'rbt/models/'
HEADER = 'frame,r11,r12,r13,r21,r22,r23,r31,r32,r33,tx,ty,tz'
GT_OK_MEDIAN_PX, GT_OK_FRAC = 1.6, 0.4    # gt_quality.csv: gt_ok = 1 when the final GT fits the silhouette this well


# ----------------------------------------------------------------------------- git
class Repo:
    def __init__(self, gitdir, commit):
        self.gitdir = gitdir
        self.commit = subprocess.check_output(
            ['git', '--git-dir', gitdir, 'rev-parse', commit + '^{commit}']).decode().strip()

    def read(self, path):
        return subprocess.check_output(['git', '--git-dir', self.gitdir, 'show', f'{self.commit}:{path}'])

    def ls(self, prefix):
        out = subprocess.check_output(['git', '--git-dir', self.gitdir, 'ls-tree', '-r', '--name-only',
                                       self.commit, prefix]).decode().split('\n')
        return [p for p in out if p]


# ----------------------------------------------------------------------------- geometry
def expSE3(xi):
    """first-order-exact enough for small steps: rotation by rotvec xi[3:], translation xi[:3]"""
    T = np.eye(4)
    T[:3, :3] = Rot.from_rotvec(xi[3:]).as_matrix()
    T[:3, 3] = xi[:3]
    return T


def skew_rows(p):
    Z = np.zeros(len(p))
    return np.stack([np.stack([Z, -p[:, 2], p[:, 1]], 1),
                     np.stack([p[:, 2], Z, -p[:, 0]], 1),
                     np.stack([-p[:, 1], p[:, 0], Z], 1)], 1)


def rot_angle_deg(R):
    return np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))


class Camera:
    def __init__(self, fx, fy, cx, cy, W, H):
        self.fx, self.fy, self.cx, self.cy, self.W, self.H = fx, fy, cx, cy, W, H

    def project(self, P):
        return np.stack([self.fx * P[:, 0] / P[:, 2] + self.cx, self.fy * P[:, 1] / P[:, 2] + self.cy], 1)

    def proj_jac(self, P):
        X, Y, Z = P[:, 0], P[:, 1], P[:, 2]
        J = np.zeros((len(P), 2, 3))
        J[:, 0, 0] = self.fx / Z
        J[:, 0, 2] = -self.fx * X / Z ** 2
        J[:, 1, 1] = self.fy / Z
        J[:, 1, 2] = -self.fy * Y / Z ** 2
        return self.project(P), J


def raster_depth(cam, V, F):
    """Z-buffer rasterisation of triangles given camera-space vertices V (OpenCV).
    Pixel centres at integer coordinates. Returns depth (inf where empty)."""
    z = V[:, 2]
    uv = cam.project(V)
    u, v = uv[:, 0], uv[:, 1]
    depth = np.full((cam.H, cam.W), np.inf)
    for a, b, c in F:
        if z[a] <= 0 or z[b] <= 0 or z[c] <= 0:
            continue
        xs = np.array([u[a], u[b], u[c]])
        ys = np.array([v[a], v[b], v[c]])
        x0 = max(int(np.ceil(xs.min())), 0)
        x1 = min(int(np.floor(xs.max())), cam.W - 1)
        y0 = max(int(np.ceil(ys.min())), 0)
        y1 = min(int(np.floor(ys.max())), cam.H - 1)
        if x0 > x1 or y0 > y1:
            continue
        X, Y = np.meshgrid(np.arange(x0, x1 + 1), np.arange(y0, y1 + 1))
        d = (ys[1] - ys[2]) * (xs[0] - xs[2]) + (xs[2] - xs[1]) * (ys[0] - ys[2])
        if abs(d) < 1e-12:
            continue
        l0 = ((ys[1] - ys[2]) * (X - xs[2]) + (xs[2] - xs[1]) * (Y - ys[2])) / d
        l1 = ((ys[2] - ys[0]) * (X - xs[2]) + (xs[0] - xs[2]) * (Y - ys[2])) / d
        l2 = 1 - l0 - l1
        inside = (l0 >= -1e-9) & (l1 >= -1e-9) & (l2 >= -1e-9)
        if not inside.any():
            continue
        iz = l0 / z[a] + l1 / z[b] + l2 / z[c]
        zz = np.where(inside, 1.0 / np.maximum(iz, 1e-12), np.inf)
        sub = depth[y0:y1 + 1, x0:x1 + 1]
        np.minimum(sub, zz, out=sub)
    return depth


# ----------------------------------------------------------------------------- source data
class Source:
    def __init__(self, repo):
        self.repo = repo
        c = json.loads(repo.read(SEQ + 'cam.json'))
        assert c.get('model', 'perspectiveProjWithoutDistortion') == 'perspectiveProjWithoutDistortion'
        self.cam = Camera(c['px'], c['py'], c['u0'], c['v0'], c['w'], c['h'])
        self.depth_scale = c.get('depthScale', 0.001)
        ap = json.loads(repo.read(SEQ + 'apriltag_data.json'))
        self.cMg = [np.array(g, float) for g in ap['grid']]
        self.NF = len(self.cMg)
        names = repo.ls(SEQ)
        self.frame_paths = sorted(p for p in names if os.path.basename(p).startswith('color_image_'))
        assert len(self.frame_paths) == self.NF, (len(self.frame_paths), self.NF)
        self.depth_paths = sorted(p for p in names if os.path.basename(p).startswith('depth_image_'))
        self.init = {o: np.array(json.loads(repo.read(SEQ + f'init/{o}.json')), float) @ A4 for o in OBJECTS}
        # board: per-tag corners (tag_corners are ViSP (i,j) = (v,u) image points)
        s = ap['tag_size'] / 2
        Pc = np.array([[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]])
        self.obs = [[] for _ in range(self.NF)]
        cells = {}
        for i, dd in enumerate(ap['detections']):
            for v in dd.values():
                gT = np.linalg.inv(self.cMg[i]) @ np.array(v['cMo'])
                cell = tuple(int(x) for x in np.round((gT[:2, 3] - 0.06) / 0.12))
                cells.setdefault(cell, []).append(gT)
                self.obs[i].append((cell, np.array(v['tag_corners'], float)[:, ::-1]))
        # measured layout: mean per-tag pose in the board frame
        self.layout = {}
        for cell, L in cells.items():
            t = np.mean([T[:3, 3] for T in L], 0)
            R = Rot.from_matrix(np.array([T[:3, :3] for T in L])).mean().as_matrix()
            self.layout[cell] = Pc @ R.T + t

    def image(self, i):
        return np.array(Image.open(io.BytesIO(self.repo.read(self.frame_paths[i]))).convert('RGB'))

    def depth(self, i):
        z = np.load(io.BytesIO(self.repo.read(self.depth_paths[i])))
        return z['data'].astype(float) * self.depth_scale

    def tag_points(self, i):
        if not self.obs[i]:
            return np.zeros((0, 3)), np.zeros((0, 2))
        return (np.vstack([self.layout[c] for c, _ in self.obs[i]]),
                np.vstack([uv for _, uv in self.obs[i]]))


class Model:
    def __init__(self, repo, name, n_fit=400000):
        self.name = name
        self.obj_bytes = repo.read(MOD + f'{name}/{name}.obj')
        self.mtl_name = None
        for line in self.obj_bytes.decode(errors='replace').splitlines():
            if line.startswith('mtllib'):
                self.mtl_name = line.split(None, 1)[1].strip()
        self.mtl_bytes = repo.read(MOD + f'{name}/{self.mtl_name}') if self.mtl_name else None
        self.mesh = trimesh.load(io.BytesIO(self.obj_bytes), file_type='obj', force='mesh', process=False)
        self.X, _ = trimesh.sample.sample_surface(self.mesh, n_fit, seed=1)   # for silhouettes
        self.gMo = None


# ----------------------------------------------------------------------------- GT refinement
G = {}   # globals shared with worker processes (fork)


def silhouette(cam, T, X):
    """Point-splat silhouette of the model at pose T. Returns the model points seen on
    the inner contour pixels and the outward unit 2D normals of the contour."""
    P = X @ T[:3, :3].T + T[:3, 3]
    uv = cam.project(P)
    iu = np.round(uv[:, 0]).astype(int)
    iv = np.round(uv[:, 1]).astype(int)
    ok = (iu >= 1) & (iu < cam.W - 1) & (iv >= 1) & (iv < cam.H - 1) & (P[:, 2] > 0)
    idx = np.nonzero(ok)[0]
    lin = iv[idx] * cam.W + iu[idx]
    o = np.lexsort((P[idx, 2], lin))
    lin_s = lin[o]
    first = np.ones(len(o), bool)
    first[1:] = lin_s[1:] != lin_s[:-1]
    pix = lin_s[first]
    pt = idx[o][first]
    mask = np.zeros(cam.H * cam.W, bool)
    mask[pix] = True
    mask = mask.reshape(cam.H, cam.W)
    owner = np.full(cam.H * cam.W, -1)
    owner[pix] = pt
    owner = owner.reshape(cam.H, cam.W)
    m2 = binary_closing(mask, iterations=1) | mask
    inner = np.zeros_like(m2)
    inner[1:-1, 1:-1] = m2[1:-1, 1:-1] & ~(m2[:-2, 1:-1] & m2[2:, 1:-1] & m2[1:-1, :-2] & m2[1:-1, 2:])
    inner &= mask
    sm = gaussian_filter(m2.astype(float), 1.5)
    gy, gx = np.gradient(sm)
    vv, uu = np.nonzero(inner)
    n = -np.stack([gx[vv, uu], gy[vv, uu]], 1)
    nn = np.linalg.norm(n, axis=1)
    keep = nn > 1e-3
    return X[owner[vv[keep], uu[keep]]], n[keep] / nn[keep, None]


def smooth_channels(img):
    return [gaussian_filter(img[:, :, c].astype(np.float32), 1.0) for c in range(3)]


def edge_search(ch, x, n, R, step=0.5):
    """strongest colour edge along each normal within +-R px; returns signed offset and magnitude"""
    K = int(round(R / step))
    k = np.arange(-K, K + 1) * step
    pos = x[:, None, :] + k[None, :, None] * n[:, None, :]
    coords = np.stack([pos[..., 1].ravel(), pos[..., 0].ravel()])
    prof = np.stack([map_coordinates(c, coords, order=1, mode='nearest').reshape(len(x), -1) for c in ch], -1)
    d = np.linalg.norm(prof[:, 2:] - prof[:, :-2], axis=2) / (2 * step)
    j = np.argmax(d, 1)
    ar = np.arange(len(x))
    mag = d[ar, j]
    jm = np.clip(j, 1, d.shape[1] - 2)
    a, b, c = d[ar, jm - 1], d[ar, jm], d[ar, jm + 1]
    den = a - 2 * b + c
    with np.errstate(divide='ignore', invalid='ignore'):
        off = np.where(np.abs(den) > 1e-9, 0.5 * (a - c) / den, 0.0)
    off = np.where((j >= 1) & (j <= d.shape[1] - 2), np.clip(off, -1, 1), 0.0)
    return k[1:-1][j] + off * step, mag


def tukey(r, c):
    w = (1 - (r / c) ** 2) ** 2
    w[np.abs(r) > c] = 0
    return w


def edge_terms(cam, ch, C, gMo, X, R, sub=2, minmag=4.0, wrt='camera'):
    """linearised silhouette residuals (px) and their Jacobian w.r.t. a left twist of
    the camera pose C (wrt='camera') or of the board-to-object pose gMo (wrt='object')"""
    T = C @ gMo
    Xo, n = silhouette(cam, T, X)
    Xo, n = Xo[::sub], n[::sub]
    P = Xo @ T[:3, :3].T + T[:3, 3]
    x, Jp = cam.proj_jac(P)
    dist, mag = edge_search(ch, x, n, R)
    good = mag > minmag
    I3 = np.repeat(np.eye(3)[None], len(P), 0)
    if wrt == 'camera':
        dP = np.concatenate([I3, -skew_rows(P)], 2)
    else:
        Q = Xo @ gMo[:3, :3].T + gMo[:3, 3]
        dP = np.einsum('ij,njk->nik', C[:3, :3], np.concatenate([I3, -skew_rows(Q)], 2))
    J = np.einsum('ni,nij,njk->nk', n, Jp, dP)
    return -dist[good], J[good]


def edge_score(cam, ch, T, X, R=10):
    """diagnostic: median |offset| (px) between model silhouette and strongest edge within R,
    and the fraction of contour points within 1.5 px"""
    Xo, n = silhouette(cam, T, X)
    P = Xo @ T[:3, :3].T + T[:3, 3]
    dist, mag = edge_search(ch, cam.project(P), n, R)
    good = mag > 4
    return float(np.median(np.abs(dist[good]))), float(np.mean(np.abs(dist[good]) < 1.5))


def huber(r, k):
    a = np.abs(r)
    return np.where(a <= k, 1.0, k / np.maximum(a, 1e-12))


def camera_step(i, C, radii, sig_tag=2.0):
    """Gauss-Newton/IRLS on the camera pose C of frame i: silhouettes of all models
    (each weighted as ~200 points, Tukey) + AprilTag corners (Huber, sigma sig_tag px).
    The corners must not be allowed to drop out (no redescending weight): with them gone,
    a camera rotated by >10 deg about the dragon fits the dragon's silhouette equally well."""
    src, models, chans = G['src'], G['models'], G['chans']
    cam = src.cam
    for R in radii:
        for _ in range(2):
            Js, rs, ws = [], [], []
            for m in models:
                r, J = edge_terms(cam, chans[i], C, m.gMo, m.X, R)
                if len(r) < 10:
                    continue
                sig = max(1.4826 * np.median(np.abs(r)), 0.5)
                Js.append(J); rs.append(r)
                ws.append(tukey(r, 4.685 * sig) * (200.0 / len(r)))
            X, U = src.tag_points(i)
            if len(X):
                P = X @ C[:3, :3].T + C[:3, 3]
                x, Jp = cam.proj_jac(P)
                dP = np.concatenate([np.repeat(np.eye(3)[None], len(P), 0), -skew_rows(P)], 2)
                r = (x - U).ravel()
                Js.append(np.einsum('nij,njk->nik', Jp, dP).reshape(-1, 6))
                rs.append(r)
                ws.append(huber(r, 2.5 * sig_tag) / sig_tag ** 2)
            J, r, w = np.vstack(Js), np.concatenate(rs), np.concatenate(ws)
            Hm = (J * w[:, None]).T @ J
            xi = -np.linalg.solve(Hm + 1e-6 * np.eye(6), (J * w[:, None]).T @ r)
            C = expSE3(xi) @ C
    return C


def fit_score(i, C, R=6):
    """fraction of silhouette points (averaged over models) within 1 px of the strongest edge"""
    src, models, chans = G['src'], G['models'], G['chans']
    s = 0.0
    for m in models:
        T = C @ m.gMo
        Xo, n = silhouette(src.cam, T, m.X)
        dist, mag = edge_search(chans[i], src.cam.project(Xo @ T[:3, :3].T + T[:3, 3]), n, R)
        s += np.mean(np.abs(dist[mag > 4]) < 1.0)
    return s / len(models)


def camera_job(args):
    i, C, radii = args
    C = camera_step(i, C, radii)
    return C, fit_score(i, C)


def refine_object(src, chans, Cs, m, radii=(6, 4, 3, 3)):
    """re-estimate the fixed board-to-object pose gMo from the silhouettes in all frames"""
    for R in radii:
        Js, rs, ws = [], [], []
        for i in range(src.NF):
            r, J = edge_terms(src.cam, chans[i], Cs[i], m.gMo, m.X, R, wrt='object')
            if len(r) < 10:
                continue
            sig = max(1.4826 * np.median(np.abs(r)), 0.5)
            Js.append(J); rs.append(r); ws.append(tukey(r, 4.685 * sig))
        J, r, w = np.vstack(Js), np.concatenate(rs), np.concatenate(ws)
        Hm = (J * w[:, None]).T @ J
        xi = -np.linalg.solve(Hm + 1e-9 * np.eye(6), (J * w[:, None]).T @ r)
        m.gMo = expSE3(xi) @ m.gMo


def refine_gt(src, models, chans, jobs, rounds=3, log=print):
    """Round 1 runs through the frames in order; each frame starts from two candidates,
    the raw board pose and the board pose corrected by the previous frame's correction,
    with a coarse-to-fine edge search (16 -> 3 px); the better silhouette fit wins.
    Then gMo of each model is re-fitted on all frames, and rounds 2.. polish every
    frame (search 5 -> 3 px) and re-fit gMo again."""
    G.update(src=src, models=models, chans=chans)
    t0 = time.time()
    pool = Pool(jobs) if jobs > 1 else None
    pmap = pool.map if pool else (lambda f, a: list(map(f, a)))
    Cs, scores, picks = [], [], []
    corr = np.eye(4)
    for i in range(src.NF):
        cands = [corr @ src.cMg[i], src.cMg[i].copy()]
        res = pmap(camera_job, [(i, c, (16, 10, 6, 4, 3, 3)) for c in cands])
        k = int(np.argmax([r[1] for r in res]))
        C = res[k][0]
        Cs.append(C); scores.append(res[k][1]); picks.append(k)
        corr = C @ np.linalg.inv(src.cMg[i])
    log(f'  GT refinement round 1/{rounds} done ({time.time() - t0:.0f} s); '
        f'{picks.count(0)} frames started from the propagated correction, {picks.count(1)} from the raw board pose')
    for m in models:
        refine_object(src, chans, Cs, m)
    for k in range(1, rounds):
        res = pmap(camera_job, [(i, Cs[i], (5, 3, 3)) for i in range(src.NF)])
        Cs = [r[0] for r in res]
        for m in models:
            refine_object(src, chans, Cs, m)
        log(f'  GT refinement round {k + 1}/{rounds} done ({time.time() - t0:.0f} s)')
    if pool:
        pool.close()
    return Cs


# ----------------------------------------------------------------------------- outputs
def write_poses(path, rows):
    with open(path, 'w') as f:
        f.write(HEADER + '\n')
        for frame, T in rows:
            v = list(T[:3, :3].ravel()) + list(T[:3, 3])
            f.write(str(frame) + ',' + ','.join(f'{x:.9f}' for x in v) + '\n')


def save_png(img, path):
    Image.fromarray(img).save(path, 'PNG', optimize=True)


def sample_model(mesh, n):
    """even-ish surface sampling with barycentric-interpolated vertex normals"""
    pts, fi = trimesh.sample.sample_surface_even(mesh, n, seed=2)
    if len(pts) < 0.9 * n:   # fall back to plain random sampling
        pts, fi = trimesh.sample.sample_surface(mesh, n, seed=2)
    tri = mesh.triangles[fi]
    bary = trimesh.triangles.points_to_barycentric(tri, pts)
    vn = mesh.vertex_normals[mesh.faces[fi]]
    nrm = np.einsum('ni,nij->nj', bary, vn)
    fn = mesh.face_normals[fi]
    bad = ~np.isfinite(nrm).all(1) | (np.linalg.norm(nrm, axis=1) < 1e-6)
    nrm[bad] = fn[bad]
    flip = np.einsum('ij,ij->i', nrm, fn) < 0     # keep interpolated normals on the face's side
    nrm[flip] = fn[flip]
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    radius = np.sqrt(mesh.area / (np.pi * len(pts))) * 1.5
    return pts, nrm, radius


def bake_colours(src, cam, mesh, pts, nrm, poses, frames, sharp):
    """average each point's colour over several GT frames where it is visible
    (mesh z-buffer + facing test + sensor-depth occlusion test)"""
    acc = np.zeros((len(pts), 3))
    wsum = np.zeros(len(pts))
    for i in frames:
        T = poses[i]
        img = src.image(i).astype(float)
        D = src.depth(i)
        P = pts @ T[:3, :3].T + T[:3, 3]
        Nc = nrm @ T[:3, :3].T
        Z = raster_depth(cam, mesh.vertices @ T[:3, :3].T + T[:3, 3], mesh.faces)
        uv = cam.project(P)
        iu = np.round(uv[:, 0]).astype(int)
        iv = np.round(uv[:, 1]).astype(int)
        ok = (uv[:, 0] >= 1) & (uv[:, 0] < cam.W - 2) & (uv[:, 1] >= 1) & (uv[:, 1] < cam.H - 2)
        cosv = -np.einsum('ij,ij->i', Nc, P / np.linalg.norm(P, axis=1, keepdims=True))
        inner = binary_erosion(np.isfinite(Z), iterations=2)      # stay 2 px away from the outline
        zb = np.full(len(P), -np.inf)
        zb[ok] = np.where(inner[iv[ok], iu[ok]], Z[iv[ok], iu[ok]], -np.inf)
        vis = ok & (cosv > 0.2) & (P[:, 2] <= zb + 0.002)
        d = np.zeros(len(P))
        d[ok] = D[iv[ok], iu[ok]]
        vis &= ~((d > 0) & (d < P[:, 2] - 0.015))          # something in front (sensor depth)
        coords = np.stack([uv[vis, 1], uv[vis, 0]])
        col = np.stack([map_coordinates(img[:, :, c], coords, order=1) for c in range(3)], 1)
        w = cosv[vis] ** 4 * (sharp[i] / sharp.max()) ** 2
        acc[vis] += w[:, None] * col
        wsum[vis] += w
    seen = wsum > 0
    rgb = np.zeros((len(pts), 3))
    rgb[seen] = acc[seen] / wsum[seen, None]
    if (~seen).any():
        rgb[~seen] = rgb[seen].mean(0)   # never observed: the mean observed colour
    return np.clip(np.round(rgb), 0, 255).astype(np.uint8), seen


def write_ply(path, pts, nrm, rgb, radius):
    n = len(pts)
    dt = np.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('nx', '<f4'), ('ny', '<f4'), ('nz', '<f4'),
                   ('red', 'u1'), ('green', 'u1'), ('blue', 'u1'), ('radius', '<f4')])
    a = np.zeros(n, dt)
    a['x'], a['y'], a['z'] = pts.T
    a['nx'], a['ny'], a['nz'] = nrm.T
    a['red'], a['green'], a['blue'] = rgb.T
    a['radius'] = radius
    hdr = ('ply\nformat binary_little_endian 1.0\n'
           'comment splattrack point model sampled from a ViSP visp-images mesh (see ../README.txt)\n'
           'comment units: metres; frame: the original .obj frame\n'
           f'element vertex {n}\n'
           'property float x\nproperty float y\nproperty float z\n'
           'property float nx\nproperty float ny\nproperty float nz\n'
           'property uchar red\nproperty uchar green\nproperty uchar blue\n'
           'property float radius\nend_header\n')
    with open(path, 'wb') as f:
        f.write(hdr.encode('ascii'))
        f.write(a.tobytes())


def sharpness(img):
    from scipy.ndimage import laplace
    g = img.astype(float) @ np.array([0.299, 0.587, 0.114])
    return float(laplace(gaussian_filter(g, 0.5)).var())


def crop_window(cam, poses, mesh, margin, sizes=((320, 240), (384, 288), (480, 360), (640, 480))):
    us, vs = [], []
    for T in poses:
        uv = cam.project(mesh.vertices @ T[:3, :3].T + T[:3, 3])
        us += [uv[:, 0].min(), uv[:, 0].max()]
        vs += [uv[:, 1].min(), uv[:, 1].max()]
    u0, u1, v0, v1 = min(us) - margin, max(us) + margin, min(vs) - margin, max(vs) + margin
    for w, h in sizes:
        if u1 - u0 <= w and v1 - v0 <= h:
            x0 = int(np.clip(round((u0 + u1) / 2 - w / 2), 0, cam.W - w))
            y0 = int(np.clip(round((v0 + v1) / 2 - h / 2), 0, cam.H - h))
            return x0, y0, w, h
    return 0, 0, cam.W, cam.H


def overlay_png(cam, img, mesh, T, path, zoom=2, pad=25):
    """model silhouette (magenta) over the frame, cropped around the object, next to the bare frame"""
    Z = raster_depth(cam, mesh.vertices @ T[:3, :3].T + T[:3, 3], mesh.faces)
    mask = np.isfinite(Z)
    e = np.zeros_like(mask)
    e[1:-1, 1:-1] = mask[1:-1, 1:-1] & ~(mask[:-2, 1:-1] & mask[2:, 1:-1] & mask[1:-1, :-2] & mask[1:-1, 2:])
    o = img.copy()
    o[e] = [255, 0, 255]
    ys, xs = np.nonzero(mask)
    y0, y1 = max(ys.min() - pad, 0), min(ys.max() + pad, cam.H)
    x0, x1 = max(xs.min() - pad, 0), min(xs.max() + pad, cam.W)
    size = ((x1 - x0) * zoom, (y1 - y0) * zoom)
    a = Image.fromarray(o[y0:y1, x0:x1]).resize(size, Image.NEAREST)
    b = Image.fromarray(img[y0:y1, x0:x1]).resize(size, Image.NEAREST)
    canvas = Image.new('RGB', (size[0] * 2 + 10, size[1]), (255, 255, 255))
    canvas.paste(a, (0, 0))
    canvas.paste(b, (size[0] + 10, 0))
    canvas.save(path)


def splat_points_png(cam, img, pts, rgb, T, path, zoom=2, pad=25):
    """the coloured model points drawn with a z-buffer at pose T, next to the frame"""
    P = pts @ T[:3, :3].T + T[:3, 3]
    uv = cam.project(P)
    iu = np.round(uv[:, 0]).astype(int)
    iv = np.round(uv[:, 1]).astype(int)
    ok = (iu >= 0) & (iu < cam.W) & (iv >= 0) & (iv < cam.H)
    out = np.full_like(img, 255)
    zb = np.full((cam.H, cam.W), np.inf)
    order = np.argsort(-P[ok, 2])       # far to near, near overwrites
    idx = np.nonzero(ok)[0][order]
    out[iv[idx], iu[idx]] = rgb[idx]
    zb[iv[idx], iu[idx]] = P[idx, 2]
    mask = np.isfinite(zb)
    ys, xs = np.nonzero(mask)
    y0, y1 = max(ys.min() - pad, 0), min(ys.max() + pad, cam.H)
    x0, x1 = max(xs.min() - pad, 0), min(xs.max() + pad, cam.W)
    size = ((x1 - x0) * zoom, (y1 - y0) * zoom)
    a = Image.fromarray(out[y0:y1, x0:x1]).resize(size, Image.NEAREST)
    b = Image.fromarray(img[y0:y1, x0:x1]).resize(size, Image.NEAREST)
    canvas = Image.new('RGB', (size[0] * 2 + 10, size[1]), (255, 255, 255))
    canvas.paste(a, (0, 0))
    canvas.paste(b, (size[0] + 10, 0))
    canvas.save(path)


# ----------------------------------------------------------------------------- verification (reads only the written files)
def read_ply(path):
    with open(path, 'rb') as f:
        hdr = b''
        while not hdr.endswith(b'end_header\n'):
            hdr += f.readline()
        lines = hdr.decode('ascii').splitlines()
        n = int([l for l in lines if l.startswith('element vertex')][0].split()[-1])
        tmap = {'float': '<f4', 'uchar': 'u1', 'double': '<f8'}
        props = [(l.split()[2], tmap[l.split()[1]]) for l in lines if l.startswith('property')]
        return np.frombuffer(f.read(), dtype=np.dtype(props), count=n)


def read_poses(path):
    rows = {}
    with open(path) as f:
        assert f.readline().strip() == HEADER, path
        for line in f:
            v = line.strip().split(',')
            T = np.eye(4)
            T[:3, :3] = np.array(v[1:10], float).reshape(3, 3)
            T[:3, 3] = np.array(v[10:13], float)
            rows[v[0]] = T
    return rows


def verify_dir(d, outdir):
    """project model.ply (z-buffered points, 2x2 px) and mesh.obj's outline with poses.csv onto the
    first/middle/last frames of a written sequence directory; print the PLY/pose sanity numbers"""
    name = os.path.basename(os.path.normpath(d))
    c = json.load(open(os.path.join(d, 'camera.json')))
    cam = Camera(c['fx'], c['fy'], c['cx'], c['cy'], c['width'], c['height'])
    ply = read_ply(os.path.join(d, 'model.ply'))
    pts = np.stack([ply['x'], ply['y'], ply['z']], 1).astype(float)
    rgb = np.stack([ply['red'], ply['green'], ply['blue']], 1)
    nrm = np.stack([ply['nx'], ply['ny'], ply['nz']], 1).astype(float)
    mesh = trimesh.load(os.path.join(d, 'mesh.obj'), force='mesh', process=False)
    poses = read_poses(os.path.join(d, 'poses.csv'))
    frames = sorted(os.listdir(os.path.join(d, 'frames')))
    init = read_poses(os.path.join(d, 'init.csv'))
    assert np.allclose(init['0'], poses['0'])
    for R in [T[:3, :3] for T in poses.values()]:
        assert abs(np.linalg.det(R) - 1) < 1e-6 and np.allclose(R @ R.T, np.eye(3), atol=1e-6)
    print(f'{name}: {len(frames)} frames {cam.W}x{cam.H}, {len(poses)} poses, {len(ply)} points, '
          f'radius {ply["radius"].mean() * 1000:.3f} mm, |n|-1 max {np.abs(np.linalg.norm(nrm, axis=1) - 1).max():.1e}, '
          f'bbox diag {np.linalg.norm(pts.max(0) - pts.min(0)):.4f} m')
    for k in (0, len(frames) // 2, len(frames) - 1):
        img = np.array(Image.open(os.path.join(d, 'frames', frames[k])).convert('RGB'))
        T = poses[str(int(os.path.splitext(frames[k])[0]))]
        P = pts @ T[:3, :3].T + T[:3, 3]
        front = np.einsum('ij,ij->i', nrm @ T[:3, :3].T, P) < 0
        uv = cam.project(P)
        out = np.full_like(img, 255)
        zb = np.full((cam.H, cam.W), np.inf)
        for du in (0, 1):
            for dv in (0, 1):
                iu = np.floor(uv[:, 0]).astype(int) + du
                iv = np.floor(uv[:, 1]).astype(int) + dv
                ok = front & (iu >= 0) & (iu < cam.W) & (iv >= 0) & (iv < cam.H)
                idx = np.nonzero(ok)[0]
                idx = idx[np.argsort(-P[idx, 2])]
                sel = P[idx, 2] < zb[iv[idx], iu[idx]] + 0.002
                idx = idx[sel]
                out[iv[idx], iu[idx]] = rgb[idx]
                zb[iv[idx], iu[idx]] = np.minimum(zb[iv[idx], iu[idx]], P[idx, 2])
        Z = raster_depth(cam, mesh.vertices @ T[:3, :3].T + T[:3, 3], mesh.faces)
        m = np.isfinite(Z)
        e = np.zeros_like(m)
        e[1:-1, 1:-1] = m[1:-1, 1:-1] & ~(m[:-2, 1:-1] & m[2:, 1:-1] & m[1:-1, :-2] & m[1:-1, 2:])
        ov = img.copy()
        ov[e] = [255, 0, 255]
        ys, xs = np.nonzero(m)
        y0, y1 = max(ys.min() - 25, 0), min(ys.max() + 25, cam.H)
        x0, x1 = max(xs.min() - 25, 0), min(xs.max() + 25, cam.W)
        tiles = [ov, out, img]
        size = ((x1 - x0) * 2, (y1 - y0) * 2)
        canvas = Image.new('RGB', (size[0] * 3 + 20, size[1]), (255, 255, 255))
        for t, a in enumerate(tiles):
            canvas.paste(Image.fromarray(np.ascontiguousarray(a[y0:y1, x0:x1])).resize(size, Image.NEAREST),
                         (t * (size[0] + 10), 0))
        canvas.save(os.path.join(outdir, f'verify_{name}_{k:04d}.png'))


# ----------------------------------------------------------------------------- main
def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('gitdir', nargs='?', help='git directory of lagadic/visp-images (bare mirror or .git)')
    ap.add_argument('--out', default=os.path.dirname(os.path.abspath(__file__)))
    ap.add_argument('--commit', default='HEAD')
    ap.add_argument('--gt', choices=['refined', 'apriltag'], default='refined')
    ap.add_argument('--points', type=int, default=100000, help='model.ply point count (approx.)')
    ap.add_argument('--jobs', type=int, default=max(1, min(os.cpu_count() or 1, 8)))
    ap.add_argument('--check', default=None, help='directory for overlay check PNGs')
    ap.add_argument('--objects', default=','.join(OBJECTS))
    ap.add_argument('--verify-only', action='store_true',
                    help='do not convert; re-read the written sequences under --out and render '
                         'verification PNGs into --check (default /tmp/datacheck)')
    args = ap.parse_args()
    log = lambda s: print(s, flush=True)
    if args.verify_only:
        outdir = args.check or '/tmp/datacheck'
        os.makedirs(outdir, exist_ok=True)
        for o in args.objects.split(','):
            verify_dir(os.path.join(args.out, f'visp_rbt_{o}'), outdir)
        return
    if not args.gitdir:
        ap.error('gitdir is required (unless --verify-only)')

    repo = Repo(args.gitdir, args.commit)
    log(f'visp-images commit {repo.commit}')
    src = Source(repo)
    cam = src.cam
    log(f'{src.NF} frames, camera {cam.W}x{cam.H} fx={cam.fx:.3f} fy={cam.fy:.3f} cx={cam.cx:.3f} cy={cam.cy:.3f}')
    models = {o: Model(repo, o) for o in OBJECTS}
    for o, m in models.items():
        m.gMo = np.linalg.inv(src.cMg[0]) @ src.init[o]
    raw = {o: [src.cMg[i] @ models[o].gMo for i in range(src.NF)] for o in OBJECTS}

    log('loading frames')
    imgs = [src.image(i) for i in range(src.NF)]
    sharp = np.array([sharpness(im) for im in imgs])
    chans = [smooth_channels(im) for im in imgs]

    if args.gt == 'refined':
        log('refining GT (joint camera refinement from board corners + cube and dragon silhouettes)')
        Cs = refine_gt(src, list(models.values()), chans, args.jobs, log=log)
        gt = {o: [Cs[i] @ models[o].gMo for i in range(src.NF)] for o in OBJECTS}
    else:
        gt = raw

    if args.check:
        os.makedirs(args.check, exist_ok=True)

    # per-frame quality of the final GT: silhouette-to-edge fit of every object (one camera per frame)
    log('scoring GT')
    score = {o: [edge_score(cam, chans[i], gt[o][i], models[o].X) for i in range(src.NF)] for o in OBJECTS}
    score_raw = {o: [edge_score(cam, chans[i], raw[o][i], models[o].X) for i in range(src.NF)] for o in OBJECTS}
    tag_rms = []
    for i in range(src.NF):
        X, U = src.tag_points(i)
        C = gt[OBJECTS[0]][i] @ np.linalg.inv(models[OBJECTS[0]].gMo)
        tag_rms.append(float(np.sqrt(np.mean(np.sum((cam.project(X @ C[:3, :3].T + C[:3, 3]) - U) ** 2, 1))))
                       if len(X) else float('nan'))
    gt_ok = np.array([all(score[o][i][0] <= GT_OK_MEDIAN_PX and score[o][i][1] >= GT_OK_FRAC for o in OBJECTS)
                      for i in range(src.NF)])
    log(f'  frames with doubtful GT (gt_ok=0): {[int(i) for i in np.nonzero(~gt_ok)[0]]}')
    usable = gt_ok if gt_ok.sum() >= 10 else np.ones(src.NF, bool)   # frames for keyframes / colour baking

    for o in args.objects.split(','):
        m = models[o]
        name = f'visp_rbt_{o}'
        d = os.path.join(args.out, name)
        log(f'writing {d}')
        for sub in ('', 'frames', 'keyframes'):
            os.makedirs(os.path.join(d, sub), exist_ok=True)
        # crop (dragon only: keeps the data small; the cube keeps full frames)
        if o == 'cube':
            x0, y0, w, h = 0, 0, cam.W, cam.H
        else:
            x0, y0, w, h = crop_window(cam, gt[o], m.mesh, margin=30)
        ccam = Camera(cam.fx, cam.fy, cam.cx - x0, cam.cy - y0, w, h)
        with open(os.path.join(d, 'camera.json'), 'w') as f:
            json.dump({'width': w, 'height': h, 'fx': cam.fx, 'fy': cam.fy, 'cx': cam.cx - x0, 'cy': cam.cy - y0},
                      f, indent=1)
            f.write('\n')
        for i in range(src.NF):
            save_png(np.ascontiguousarray(imgs[i][y0:y0 + h, x0:x0 + w]), os.path.join(d, 'frames', f'{i:06d}.png'))
        write_poses(os.path.join(d, 'poses.csv'), [(i, gt[o][i]) for i in range(src.NF)])
        write_poses(os.path.join(d, 'init.csv'), [(0, gt[o][0])])
        write_poses(os.path.join(d, 'poses_apriltag.csv'), [(i, raw[o][i]) for i in range(src.NF)])
        # per-frame quality numbers
        other = [x for x in OBJECTS if x != o]
        with open(os.path.join(d, 'gt_quality.csv'), 'w') as f:
            f.write('frame,sharpness,edge_median_px,edge_frac_1p5px,' +
                    ''.join(f'{x}_edge_median_px,' for x in other) +
                    'tag_rms_px,edge_median_px_apriltag,edge_frac_1p5px_apriltag,diff_to_apriltag_px,'
                    'rot_diff_to_apriltag_deg,gt_ok\n')
            V = m.mesh.vertices if len(m.mesh.vertices) < 2000 else m.mesh.vertices[::len(m.mesh.vertices) // 2000]
            for i in range(src.NF):
                s1, s0 = score[o][i], score_raw[o][i]
                Tg, Tr = gt[o][i], raw[o][i]
                dd = np.linalg.norm(cam.project(V @ Tg[:3, :3].T + Tg[:3, 3]) -
                                    cam.project(V @ Tr[:3, :3].T + Tr[:3, 3]), axis=1).mean()
                f.write(f'{i},{sharp[i]:.1f},{s1[0]:.3f},{s1[1]:.3f},' +
                        ''.join(f'{score[x][i][0]:.3f},' for x in other) +
                        f'{tag_rms[i]:.3f},{s0[0]:.3f},{s0[1]:.3f},{dd:.3f},'
                        f'{rot_angle_deg(Tg[:3, :3] @ Tr[:3, :3].T):.3f},{int(gt_ok[i])}\n')
        # keyframes: the sharpest frame in each third of the sequence
        thirds = [t[usable[t] & (t > 0)] for t in np.array_split(np.arange(src.NF), 3)]
        kfs = [int(t[np.argmax(sharp[t])]) for t in thirds if len(t)]
        for k in kfs:
            save_png(np.ascontiguousarray(imgs[k][y0:y0 + h, x0:x0 + w]), os.path.join(d, 'keyframes', f'{k:06d}.png'))
        write_poses(os.path.join(d, 'keyframes', 'poses.csv'), [(f'{k:06d}', gt[o][k]) for k in kfs])
        # mesh (untouched) + point model
        with open(os.path.join(d, 'mesh.obj'), 'wb') as f:
            f.write(m.obj_bytes)
        if m.mtl_bytes is not None:
            with open(os.path.join(d, m.mtl_name), 'wb') as f:
                f.write(m.mtl_bytes)
        pts, nrm, radius = sample_model(m.mesh, args.points)
        bake = [i for i in range(src.NF) if sharp[i] >= np.percentile(sharp, 60) and usable[i]]
        rgb, seen = bake_colours(src, cam, m.mesh, pts, nrm, gt[o], bake, sharp)
        write_ply(os.path.join(d, 'model.ply'), pts, nrm, rgb, radius)
        ext = m.mesh.bounds[1] - m.mesh.bounds[0]
        info = {'object': o, 'gt': args.gt, 'gt_doubtful_frames': [int(i) for i in np.nonzero(~gt_ok)[0]],
                'points': int(len(pts)), 'radius_m': float(radius), 'seen_fraction': float(seen.mean()),
                'bake_frames': bake, 'keyframes': kfs, 'crop_xywh': [x0, y0, w, h],
                'bbox_extent_m': ext.tolist(), 'bbox_diagonal_m': float(np.linalg.norm(ext)),
                'commit': repo.commit}
        log('  ' + json.dumps(info))
        with open(os.path.join(d, 'conversion_info.json'), 'w') as f:
            json.dump(info, f, indent=1)
            f.write('\n')
        if args.check:
            for i in (0, src.NF // 2, src.NF - 1):
                full = imgs[i]
                overlay_png(cam, full, m.mesh, gt[o][i], os.path.join(args.check, f'{name}_overlay_{i:04d}.png'))
                overlay_png(cam, full, m.mesh, raw[o][i], os.path.join(args.check, f'{name}_overlay_apriltag_{i:04d}.png'))
                splat_points_png(cam, full, pts, rgb, gt[o][i], os.path.join(args.check, f'{name}_points_{i:04d}.png'))
            # and from the written files: first frame of the (possibly cropped) sequence
            fr = np.array(Image.open(os.path.join(d, 'frames', '000000.png')).convert('RGB'))
            overlay_png(ccam, fr, m.mesh, gt[o][0], os.path.join(args.check, f'{name}_written_overlay_0000.png'))
            verify_dir(d, args.check)
    log('done')


if __name__ == '__main__':
    main()
