"""Visual-inertial odometry benchmark (issue 25; not a timed test).

Generates once a 60 s aggressive flight (EuRoC-like: up to about 2 m/s and 90 deg/s; stereo 640x480 at 20 Hz, IMU at
200 Hz with the ICM-42688-P's datasheet noise and small calibrated-residual biases) and runs on the same data:

* ``--world vio_room`` (the default): the built-in ``vio_room`` world (posters, shelves, brick and concrete, sun and
  shadows) rendered by cufund's C++ renderer with the ``stereo_camera`` kind's default rig (grey, 11 cm baseline,
  shadows on, no sensor noise), the images a ``square_vio`` flight gets;
* ``--world synthetic``: the noise-textured box room of :mod:`cufund.estimation.vio_synthetic` (exact ray casting
  in numpy), same size, same rig.

The estimators:

* cufund's VIO (``VioCore``: KLT + GTSAM fixed-lag smoother), stereo + IMU and mono + IMU (the left images);
* a peer: ORB-SLAM3 stereo-inertial through PyPI ``orbslam3-python`` when it imports (``--orbslam``, see below),
  and always an OpenCV stereo visual odometry baseline (ORB features, stereo triangulation, PnP RANSAC frame to
  frame, no IMU; started at the true pad pose, an advantage the VIO does not get).

ORB-SLAM3 needs its ORB vocabulary (ORBvoc.txt, not shipped in the wheel and not downloadable here):
``--orbslam VOCABULARY`` runs it with the given file.

Errors: position RMSE (unaligned: every estimator's world frame is the pad's) and rotation RMSE at every output
after the 1 s still start (the VIO's at IMU rate, the peers' at the camera frames), and the median wall time per stereo frame. One table.

    .venv/bin/python benchmarks/bench_vio.py [--world vio_room|synthetic] [--duration 60] [--cache /tmp/vio.npz]
        [--orbslam VOC]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from cufund.estimation.evaluation import aligned_ate, odometry_errors
from cufund.estimation.vio_core import VioCore
from cufund.estimation.vio_params import VioCamera, VioParams
from cufund.estimation.vio_synthetic import SyntheticRun, TexturedRoom, hover_then, synthesize
from cufund.geometry import Transform, quat_from_matrix, quat_to_matrix
from cufund.sensors.camera import RgbCamera
from cufund.sensors.imu import imu_preset
from cufund.sensors.kinds import StereoCameraParams
from cufund.worlds.vio_room import vio_room

RIG = StereoCameraParams()
"""The stereo_camera kind's default rig (square_vio's): 640x480, 11 cm baseline, grey, shadows."""
CAM0, CAM1 = (
    VioCamera(
        c.intrinsics.width,
        c.intrinsics.height,
        c.intrinsics.fx,
        c.intrinsics.fy,
        c.intrinsics.cx,
        c.intrinsics.cy,
        T_BC=c.T_BC,
    )
    for c in RIG.cameras()[:2]
)
WORLDS = ("vio_room", "synthetic")
START = (0.0, 0.0, 1.4)
ACCEL_BIAS = (0.02, -0.015, 0.01)
"""What a calibration leaves [m/s^2] (about 2 mg), unknown to the estimators."""
GYRO_BIAS = (0.002, -0.0015, 0.001)
"""[rad/s] (the VIO finds it on the pad)."""


def aggressive(t: float) -> tuple[float, float, float, float, float, float]:
    """(dx, dy, dz, yaw, pitch, roll): up to about 2 m/s and 90 deg/s in an 8 x 6 x 3 m room."""
    return (
        1.6 * math.sin(0.75 * t) + 0.25 * math.sin(2.1 * t),
        1.15 * math.sin(0.55 * t + 0.5) + 0.2 * math.sin(1.7 * t),
        0.35 * math.sin(1.1 * t),
        1.1 * math.sin(1.05 * t) + 0.3 * math.sin(2.3 * t),
        0.2 * math.sin(1.6 * t),
        0.2 * math.sin(1.3 * t + 1.0),
    )


class RenderedRoom:
    """The ``vio_room`` world through cufund's renderer, as ``synthesize`` asks a room for an image: the grey image
    of a camera (its intrinsics) at an optical-frame pose (x right, y down, z forward)."""

    _R_CO = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    """Optical frame -> camera frame (FLU, the renderer's)."""

    def __init__(self, seed: int = 0) -> None:
        self.world = vio_room(seed)
        self.camera = RgbCamera(
            RIG.intrinsics,
            None,  # the pose given is the camera's own
            light_W=RIG.light_W,
            ambient=RIG.ambient,
            shadows=RIG.shadows,
            grayscale=True,
            full_well_e=RIG.full_well_e,
            read_noise_dn=RIG.read_noise_dn,
        )

    def render(self, R_WO: np.ndarray, p_WO: np.ndarray, cam: VioCamera) -> np.ndarray:
        k = RIG.intrinsics
        if (cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy) != (k.width, k.height, k.fx, k.fy, k.cx, k.cy):
            raise ValueError("RenderedRoom renders the rig's intrinsics only")
        image = self.camera.render(self.world, p_WO, quat_from_matrix(R_WO @ self._R_CO.T))
        assert isinstance(image, np.ndarray)
        return image


def generate(duration: float, world: str = "vio_room"):
    imu = imu_preset("icm42688p")
    run = synthesize(
        hover_then(aggressive, START, t_static=1.5, t_ramp=2.0),
        duration,
        CAM0,
        CAM1,
        RenderedRoom() if world == "vio_room" else TexturedRoom(seed=7),
        imu_hz=200.0,
        cam_hz=20.0,
        accel_noise=imu.accel.white_noise_density,
        gyro_noise=imu.gyro.white_noise_density,
        accel_bias=ACCEL_BIAS,
        gyro_bias=GYRO_BIAS,
        seed=7,
    )
    return run


def run_vio(run, mono: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[tuple[float, float]]]:
    """(t, p, q) of cufund's VIO at every IMU sample (its output), and its wall time per stereo frame [ms]; with
    ``mono`` on the left images alone (mono + IMU)."""
    core = VioCore(VioParams(cam0=CAM0, cam1=None if mono else CAM1, p_WB0=START, imu=imu_preset("icm42688p")))
    fi, ts, ps, qs, ms = 0, [], [], [], []
    for t, f, w in run.imu:
        while fi < len(run.frames) and run.frames[fi][0] < t:
            w0, c0 = time.perf_counter(), time.process_time()
            core.add_frame(*(run.frames[fi][:2] if mono else run.frames[fi]))
            ms.append(((time.perf_counter() - w0) * 1e3, (time.process_time() - c0) * 1e3))
            fi += 1
        o = core.add_imu(t, f, w)
        if o is not None:  # the IMU-rate output the controllers fly on
            ts.append(o.t)
            ps.append(o.p_W)
            qs.append(o.q_WB)
    return np.array(ts), np.array(ps), np.array(qs), ms


class StereoVoBaseline:
    """OpenCV stereo visual odometry: ORB on both images, left-right matches on the same row triangulated, the
    reference keyframe's points matched to the new left image and PnP RANSAC for the motion (a new reference
    keyframe when fewer than ``min_inliers`` remain); poses chained over keyframes. No IMU.
    Keypoints are refined to sub-pixel positions before triangulation and PnP."""

    def __init__(self, cam: VioCamera, baseline: float, T_BC: Transform) -> None:
        self.K = cam.K
        self.f, self.b = cam.fx, baseline
        self.orb = cv2.ORB_create(1500)
        self.bf = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=True)
        R_CO = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
        self.T_BO = np.eye(4)
        self.T_BO[:3, :3], self.T_BO[:3, 3] = T_BC.R @ R_CO, T_BC.t
        self.prev: tuple[np.ndarray, np.ndarray] | None = None
        self.T_WO = np.eye(4)
        self.T_W_ref = np.eye(4)
        self.min_inliers = 150
        """A new reference keyframe when fewer of its points are PnP inliers."""

    @staticmethod
    def _subpixel(image: np.ndarray, kps) -> np.ndarray:
        """Keypoint positions refined to a fraction of a pixel (ORB's come on its pyramid levels' grids)."""
        if not kps:
            return np.zeros((0, 2))
        pts = np.array([k.pt for k in kps], np.float32).reshape(-1, 1, 2)
        crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.01)
        return cv2.cornerSubPix(image, pts, (3, 3), (-1, -1), crit).reshape(-1, 2).astype(float)

    def start(self, R_WB: np.ndarray, p_WB: np.ndarray) -> None:
        T_WB = np.eye(4)
        T_WB[:3, :3], T_WB[:3, 3] = R_WB, p_WB
        self.T_WO = T_WB @ self.T_BO

    def process(self, left: np.ndarray, right: np.ndarray) -> np.ndarray:
        """T_WB after this frame."""
        kl, dl = self.orb.detectAndCompute(left, None)
        kr, dr = self.orb.detectAndCompute(right, None)
        pl, pr = self._subpixel(left, kl), self._subpixel(right, kr)
        pts3, desc = np.zeros((0, 3)), None
        if dl is not None and dr is not None:
            m = self.bf.match(dl, dr)
            ul = pl[[x.queryIdx for x in m]].reshape(-1, 2)
            ur = pr[[x.trainIdx for x in m]].reshape(-1, 2)
            d = ul[:, 0] - ur[:, 0]
            ok = (np.abs(ul[:, 1] - ur[:, 1]) < 1.5) & (d > 0.5)
            z = self.f * self.b / d[ok]
            K = self.K
            pts3 = np.column_stack([(ul[ok, 0] - K[0, 2]) * z / K[0, 0], (ul[ok, 1] - K[1, 2]) * z / K[1, 1], z])
            desc = dl[[x.queryIdx for x in np.array(m, dtype=object)[ok]]] if ok.any() else None
        inliers = 0
        if self.prev is not None and dl is not None:
            P, D = self.prev  # the reference keyframe's points (its optical frame) and descriptors
            m = self.bf.match(D, dl)
            if len(m) >= 6:
                X = P[[x.queryIdx for x in m]]
                uv = pl[[x.trainIdx for x in m]]
                ok, rvec, tvec, inl = cv2.solvePnPRansac(
                    X, uv, self.K, None, reprojectionError=1.5, iterationsCount=200
                )
                if ok and inl is not None and len(inl) >= 6:
                    i = inl.reshape(-1)
                    inliers = len(i)
                    rvec, tvec = cv2.solvePnPRefineLM(X[i], uv[i], self.K, None, rvec, tvec)
                    T = np.eye(4)  # reference optical frame -> current: X_cur = R X_ref + t
                    T[:3, :3], T[:3, 3] = cv2.Rodrigues(rvec)[0], tvec.reshape(3)
                    self.T_WO = self.T_W_ref @ np.linalg.inv(T)
        if desc is not None and (self.prev is None or inliers < self.min_inliers):
            self.prev = (pts3, desc)  # a new reference keyframe
            self.T_W_ref = self.T_WO.copy()
        return self.T_WO @ np.linalg.inv(self.T_BO)


def run_peer(run) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[tuple[float, float]]]:
    vo = StereoVoBaseline(CAM0, RIG.baseline, CAM0.T_BC)
    vo.start(quat_to_matrix(run.truth_q[0]), run.truth_p[0])
    ts, ps, qs, ms = [], [], [], []
    for t, left, right in run.frames:
        w0, c0 = time.perf_counter(), time.process_time()
        T = vo.process(left, right)
        ms.append(((time.perf_counter() - w0) * 1e3, (time.process_time() - c0) * 1e3))
        ts.append(t)
        ps.append(T[:3, 3].copy())
        qs.append(quat_from_matrix(T[:3, :3]))
    return np.array(ts), np.array(ps), np.array(qs), ms


def run_orbslam(
    run, vocabulary: str, workdir: Path
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[tuple[float, float]]]:
    """ORB-SLAM3 stereo-inertial through orbslam3-python (its vocabulary given)."""
    import orbslam3

    imu = imu_preset("icm42688p")
    settings = workdir / "orbslam3_stereo_inertial.yaml"
    R_CO = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    T_BO = np.eye(4)
    T_BO[:3, :3], T_BO[:3, 3] = CAM0.T_BC.R @ R_CO, CAM0.T_BC.t
    rows = ", ".join(f"{v:.9f}" for v in T_BO.reshape(-1))
    settings.write_text(
        "%YAML:1.0\n"
        'File.version: "1.0"\nCamera.type: "Rectified"\n'
        f"Camera1.fx: {CAM0.fx}\nCamera1.fy: {CAM0.fy}\nCamera1.cx: {CAM0.cx}\nCamera1.cy: {CAM0.cy}\n"
        "Camera1.k1: 0.0\nCamera1.k2: 0.0\nCamera1.p1: 0.0\nCamera1.p2: 0.0\n"
        f"Camera.width: {CAM0.width}\nCamera.height: {CAM0.height}\nCamera.fps: 20\nCamera.RGB: 0\n"
        f"Stereo.ThDepth: 60.0\nStereo.b: {RIG.baseline}\n"
        f"IMU.T_b_c1: !!opencv-matrix\n  rows: 4\n  cols: 4\n  dt: f\n  data: [{rows}]\n"
        f"IMU.NoiseGyro: {imu.gyro.white_noise_density}\nIMU.NoiseAcc: {imu.accel.white_noise_density}\n"
        f"IMU.GyroWalk: {imu.gyro.bias_random_walk}\nIMU.AccWalk: {imu.accel.bias_random_walk}\nIMU.Frequency: 200.0\n"
        "ORBextractor.nFeatures: 1200\nORBextractor.scaleFactor: 1.2\nORBextractor.nLevels: 8\n"
        "ORBextractor.iniThFAST: 20\nORBextractor.minThFAST: 7\n"
        "Viewer.KeyFrameSize: 0.05\nViewer.KeyFrameLineWidth: 1.0\nViewer.GraphLineWidth: 0.9\nViewer.PointSize: 2.0\n"
        "Viewer.CameraSize: 0.08\nViewer.CameraLineWidth: 3.0\nViewer.ViewpointX: 0.0\nViewer.ViewpointY: -0.7\n"
        "Viewer.ViewpointZ: -1.8\nViewer.ViewpointF: 500.0\n"
    )
    slam = orbslam3.System(vocabulary, str(settings), orbslam3.Sensor.IMU_STEREO)
    slam.initialize()
    ts, ps, qs, ms = [], [], [], []
    ii = 0
    for t, left, right in run.frames:
        batch = []
        while ii < len(run.imu) and run.imu[ii][0] <= t:
            ti, f, w = run.imu[ii]
            batch.append((float(f[0]), float(f[1]), float(f[2]), float(w[0]), float(w[1]), float(w[2]), float(ti)))
            ii += 1
        w0, c0 = time.perf_counter(), time.process_time()
        slam.process_stereo_inertial_enhanced(left, right, t, batch)
        ms.append(((time.perf_counter() - w0) * 1e3, (time.process_time() - c0) * 1e3))
        T = slam.get_frame_pose()
        if T is None or np.asarray(T).shape != (4, 4):
            continue
        T_cw = np.asarray(T, dtype=float)  # camera pose: world (its first camera frame) to camera
        ts.append(t)
        T_wc = np.linalg.inv(T_cw)
        ps.append(T_wc[:3, 3])
        qs.append(quat_from_matrix(T_wc[:3, :3]))
    return np.array(ts), np.array(ps), np.array(qs), ms


def errors(run, t: np.ndarray, p: np.ndarray, q: np.ndarray) -> dict[str, float]:
    """Unaligned figures (the estimate's world frame is the pad's) and evo's aligned ATE (SE(3) Umeyama)."""
    keep = t >= 1.0
    i = np.searchsorted(run.truth_t, t[keep] - 1e-9)
    e = odometry_errors(p[keep], q[keep], run.truth_p[i], run.truth_q[i])
    e["ate_aligned_m"] = aligned_ate(p[keep], run.truth_p[i])
    return e


def save_run(path: Path, run: SyntheticRun, world: str) -> None:
    """The flight as plain arrays (``.npz``): a cache file that loading cannot make run anything (no pickle)."""
    with open(path, "wb") as f:  # a file object: np.savez appends no ".npz" to the name
        np.savez(
            f,
            imu_t=np.array([s[0] for s in run.imu]),
            imu_f=np.array([s[1] for s in run.imu]),
            imu_w=np.array([s[2] for s in run.imu]),
            frame_t=np.array([fr[0] for fr in run.frames]),
            left=np.stack([fr[1] for fr in run.frames]),
            right=np.stack([fr[2] for fr in run.frames]),
            truth_t=run.truth_t,
            truth_p=run.truth_p,
            truth_q=run.truth_q,
            world=np.array(world),
        )


def load_run(path: Path, world: str) -> SyntheticRun:
    """The flight :func:`save_run` wrote (a ValueError when it was flown in another world)."""
    with np.load(path, allow_pickle=False) as z:
        cached = str(z["world"]) if "world" in z.files else "synthetic"
        if cached != world:
            raise ValueError(f"{path} holds a flight in {cached!r}, not {world!r}: give another --cache")
        return SyntheticRun(
            imu=list(zip(z["imu_t"].tolist(), z["imu_f"], z["imu_w"], strict=True)),
            frames=list(zip(z["frame_t"].tolist(), z["left"], z["right"], strict=True)),
            truth_t=z["truth_t"],
            truth_p=z["truth_p"],
            truth_q=z["truth_q"],
        )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--world", choices=WORLDS, default="vio_room", help="where the flight is rendered (see above)")
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument(
        "--cache", type=Path, default=None, help="keep the generated flight here (.npz, arrays only) and reuse it"
    )
    ap.add_argument("--orbslam", default="", help="ORB-SLAM3 vocabulary file: run ORB-SLAM3 stereo-inertial too")
    ap.add_argument(
        "--orbslam-path",
        default="",
        help="folder orbslam3-python was installed into when not in the venv (pip install --target DIR "
        "orbslam3-python: its wheel brings its own numpy and OpenCV, kept out of the venv); appended to sys.path",
    )
    args = ap.parse_args(argv)
    w0 = time.perf_counter()
    if args.cache is not None and args.cache.exists():
        try:
            run = load_run(args.cache, args.world)
        except ValueError as e:
            ap.error(str(e))
    else:
        run = generate(args.duration, args.world)
        if args.cache is not None:
            save_run(args.cache, run, args.world)
    print(
        f"flight in {args.world}: {run.truth_t[-1]:.0f} s, {len(run.frames)} stereo frames 640x480, "
        f"{len(run.imu)} IMU samples "
        f"(generated in {time.perf_counter() - w0:.0f} s)"
    )
    v = np.gradient(run.truth_p, run.truth_t, axis=0)
    print(f"  peak speed {np.linalg.norm(v, axis=1).max():.2f} m/s")
    rows = [
        ("cufund VIO (stereo + IMU, GTSAM)", run_vio(run)),
        ("cufund VIO (mono + IMU, GTSAM)", run_vio(run, mono=True)),
        ("OpenCV stereo VO (PnP RANSAC, no IMU)", run_peer(run)),
    ]
    if args.orbslam_path:
        sys.path.append(args.orbslam_path)
    if args.orbslam:
        try:
            rows.append(("ORB-SLAM3 stereo-inertial", run_orbslam(run, args.orbslam, Path("/tmp"))))
        except Exception as e:  # report and go on with the others
            print(f"ORB-SLAM3: {type(e).__name__}: {e}", file=sys.stderr)
    print(f"load average: {' '.join(f'{x:.1f}' for x in os.getloadavg())} on {os.cpu_count()} cores")
    print(
        f"{'estimator':40s} {'pos RMSE cm':>11s} {'max cm':>7s} {'rot RMSE deg':>12s} {'ATE aligned cm':>14s} "
        f"{'wall ms/frame':>13s} {'CPU ms/frame':>12s} {'outputs':>8s}"
    )
    for name, (t, p, q, ms) in rows:
        if len(t) == 0:
            print(f"{name:40s} {'no output':>11s}")
            continue
        e = errors(run, t, p, q)
        own_frame = name != "ORB-SLAM3 stereo-inertial"  # ORB-SLAM3's world frame is its own: aligned only
        wall, cpu = np.median(np.array(ms), axis=0)
        print(
            f"{name:40s} {e['odometry_rmse_m'] * 100 if own_frame else math.nan:11.2f} "
            f"{e['odometry_max_m'] * 100 if own_frame else math.nan:7.2f} "
            f"{e['odometry_rot_rmse_deg'] if own_frame else math.nan:12.3f} {e['ate_aligned_m'] * 100:14.2f} "
            f"{wall:13.1f} {cpu:12.1f} {len(t):8d}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
