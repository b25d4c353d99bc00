"""The LiDAR-inertial odometry core: IMU samples and LiDAR frames in, body odometry out. No simulator needed.

State: the IMU frame's pose T_WI, velocity v_WI and IMU biases at each LiDAR frame's end, in GTSAM's
``IncrementalFixedLagSmoother``; ``CombinedImuFactor`` between consecutive frames from every IMU sample (noise
from the IMU's noise spec, in the IMU frame); one LiDAR factor per frame from scan-to-map registration of the
deskewed scan. Between frames the last estimate is propagated through each IMU sample (the IMU-rate output).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import gtsam
import numpy as np
from gtsam.symbol_shorthand import B, V, X

from cufund import _core
from cufund.core.messages import Odometry
from cufund.geometry import attitude_from_up_and_yaw, homogeneous, quat_from_matrix, quat_to_matrix

from .boundary import pose3, pose3_parts
from .params import LioParams
from .registration import PlaneModel, fit_planes, observable_split, plane_terms, register

__all__ = ["LioCore", "ScanDiagnostics", "NavEstimate"]

_MIN_ADVANCE_S = 0.02
"""A frame must end at least this long after the newest state to add one [s]."""
_PAD_FRAMES_KEPT = 30
"""LiDAR frames taken on the pad that seed the map (the newest ones)."""


@dataclass(frozen=True)
class ScanDiagnostics:
    """One LiDAR frame's processing (the issue's OdometryDiagnostics fields)."""

    t: float
    """Frame end time (the estimate's stamp) [s]."""
    points: int
    """Points after deskewing, range filtering and downsampling."""
    inliers: int
    iterations: int
    eigenvalues: tuple[float, ...]
    """Normalised Hessian eigenvalues, ascending (see LioParams.degeneracy_threshold)."""
    degenerate_directions: tuple[tuple[float, ...], ...]
    """Weakly observable directions in the world frame, each [rotation (3), translation (3)]."""
    time_ms: float
    """Wall time spent on this frame [ms]."""
    cpu_ms: float = 0.0
    """CPU time of the process (all threads) spent on this frame [ms]: the cost on a busy machine."""
    skipped: str = ""
    """Why the frame added no LiDAR factor ('' when it did)."""
    innovation_deg: float = 0.0
    """Rotation between the IMU-propagated prediction and the registered pose [deg]."""
    innovation_m: float = 0.0
    """Distance between the IMU-propagated prediction and the registered position [m]."""
    healthy: bool = True
    """False while the estimate should not be trusted for precise flight (see LioCore.health)."""
    reason: str = ""
    """Why it is not healthy ('' when it is)."""


@dataclass
class NavEstimate:
    """IMU-frame navigation state."""

    t: float
    R_WI: np.ndarray
    p_W: np.ndarray
    v_W: np.ndarray
    bias_acc: np.ndarray
    bias_gyr: np.ndarray


@dataclass
class _ImuBuffer:
    t: list[float] = field(default_factory=list)
    acc: list[np.ndarray] = field(default_factory=list)
    gyr: list[np.ndarray] = field(default_factory=list)

    def pieces(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Zero-order-hold pieces covering [t0, t1]: (knot times (n+1,), dt (n,), acc (n, 3), gyr (n, 3)). The sample
        at or before t0 starts it; the last sample is held to t1."""
        ts = np.asarray(self.t)
        i0 = max(int(np.searchsorted(ts, t0, side="right")) - 1, 0)
        i1 = int(np.searchsorted(ts, t1, side="left"))  # samples strictly before t1
        idx = np.arange(i0, max(i1, i0 + 1))
        knots = np.concatenate([[t0], ts[idx[1:]], [t1]])
        dt = np.diff(knots)
        keep = dt > 0
        acc = np.asarray(self.acc)[idx][keep]
        gyr = np.asarray(self.gyr)[idx][keep]
        knots = np.concatenate([[t0], knots[1:][keep]])
        return knots, dt[keep], acc, gyr

    def prune(self, t_keep: float) -> None:
        i = int(np.searchsorted(np.asarray(self.t), t_keep, side="right")) - 1
        if i > 0:
            del self.t[:i], self.acc[:i], self.gyr[:i]


def _so3_log(R: np.ndarray) -> np.ndarray:
    """The rotation vector of R [rad]."""
    c = float(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))
    th = math.acos(c)
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return v * (0.5 if th < 1e-6 else th / (2.0 * math.sin(th)))


class LioCore:
    """``add_imu(t, f_I, w_I)`` for every IMU sample, ``add_scan(t, dt, points_L)`` for every LiDAR frame (after
    the IMU samples up to its end). Both return the body ``Odometry`` they produce, or None (still initialising)."""

    def __init__(self, params: LioParams | None = None) -> None:
        self.params = params or LioParams()
        p = self.params
        self._R_BI = quat_to_matrix(np.asarray(p.imu.q_BI), normalize=True)
        self._p_BI = np.asarray(p.imu.p_BI, dtype=float)
        self._T_BI = np.eye(4)
        self._T_BI[:3, :3], self._T_BI[:3, 3] = self._R_BI, self._p_BI
        self._T_BL = homogeneous(p.T_BL)
        T_IL = np.linalg.inv(self._T_BI) @ self._T_BL
        self._R_IL, self._p_IL = T_IL[:3, :3], T_IL[:3, 3]
        self._g = np.array([0.0, 0.0, -p.gravity])
        self._imu = _ImuBuffer()
        self._map = _core.odometry.VoxelMap(
            p.map_voxel, p.map_points_per_voxel, p.map_min_point_distance, p.map_max_distance, p.map_max_voxels
        )
        self._model = PlaneModel(self._map, p)
        self._pim_params = self._imu_params()
        self._pim_recovery = self._imu_params(p.recovery_acc_rw, p.recovery_gyro_rw)
        isam = gtsam.ISAM2Params()
        isam.setRelinearizeThreshold(p.relinearize_threshold)
        isam.relinearizeSkip = 1
        self._smoother = gtsam.IncrementalFixedLagSmoother(p.lag_s, isam)
        self._node: NavEstimate | None = None  # estimate at the last node
        self._k = -1
        self._now: NavEstimate | None = None  # propagated to the newest IMU sample
        self._last_sample: tuple[np.ndarray, np.ndarray] | None = None
        self.diagnostics: list[ScanDiagnostics] = []
        self._pad_frames: list[np.ndarray] = []
        self.skipped_imu = 0
        self.skipped_scans = 0
        self.dropped_points = 0
        self.last_lidar_factor_t: float | None = None
        """End of the newest frame that added a LiDAR constraint [s] (None before the first)."""
        self._consistent = self.params.health_relock_frames  # consistent frames in a row

    # ---------------------------------------------------------------- setup
    def _imu_params(self, acc_rw_min: float = 0.0, gyr_rw_min: float = 0.0) -> gtsam.PreintegrationCombinedParams:
        """The IMU factors' noise from the IMU's spec; the bias random walks at least ``acc_rw_min`` and
        ``gyr_rw_min`` (the loose factors that let the biases follow a jump)."""
        ip = self.params.imu
        acc_w, acc_rw, _ = ip.accel.per_axis(3)
        gyr_w, gyr_rw, _ = ip.gyro.per_axis(3)
        acc_rw, gyr_rw = np.maximum(acc_rw, acc_rw_min), np.maximum(gyr_rw, gyr_rw_min)

        # An ideal IMU (zero densities) still needs a well-conditioned problem: its zeros become small densities
        # (a real part's spec is used as given).
        def density(x: np.ndarray, floor: float) -> np.ndarray:
            return np.diag(np.where(x > 0, x, floor) ** 2)

        pim = gtsam.PreintegrationCombinedParams(self._g)
        pim.setAccelerometerCovariance(density(acc_w, 1e-3))
        pim.setGyroscopeCovariance(density(gyr_w, 1e-4))
        pim.setBiasAccCovariance(density(acc_rw, 1e-4))
        pim.setBiasOmegaCovariance(density(gyr_rw, 1e-5))
        pim.setIntegrationCovariance(np.eye(3) * 1e-10)
        return pim

    @property
    def initialised(self) -> bool:
        return self._node is not None

    @property
    def voxel_map(self) -> _core.odometry.VoxelMap:
        return self._map

    # ---------------------------------------------------------------- IMU
    def add_imu(self, t: float, f_I: np.ndarray, w_I: np.ndarray) -> Odometry | None:
        f = np.asarray(f_I, dtype=float).reshape(-1)
        w = np.asarray(w_I, dtype=float).reshape(-1)
        if f.shape != (3,) or w.shape != (3,) or not (np.all(np.isfinite(f)) and np.all(np.isfinite(w))):
            raise ValueError(f"f_I and w_I must be 3 finite numbers each, got {f_I!r}, {w_I!r}")
        if not math.isfinite(t):
            raise ValueError(f"t must be finite [s], got {t!r}")
        if self._imu.t and t <= self._imu.t[-1]:
            self.skipped_imu += 1  # out of order or repeated: counted, never integrated
            return None
        self._imu.t.append(float(t))
        self._imu.acc.append(f)
        self._imu.gyr.append(w)
        if self._node is None:
            self._try_initialise()
            return self._odometry(self._now) if self._now is not None else None
        assert self._now is not None  # set with the node
        prev_t = self._now.t
        if self._last_sample is not None and t > prev_t:
            acc, gyr = self._last_sample
            self._now = self._propagate(self._now, np.array([t - prev_t]), acc[None], gyr[None])[-1]
        self._last_sample = (f, w)
        return self._odometry(self._now)

    def _try_initialise(self) -> None:
        p = self.params
        ts = np.asarray(self._imu.t)
        if ts[-1] - ts[0] < p.init_duration_s:
            return
        acc, gyr = np.asarray(self._imu.acc), np.asarray(self._imu.gyr)
        f_mean, w_mean = acc.mean(axis=0), gyr.mean(axis=0)
        dev_w = float(np.max(np.linalg.norm(gyr - w_mean, axis=1)))
        dev_f = float(np.max(np.linalg.norm(acc - f_mean, axis=1)))
        if dev_w > p.init_max_gyro_dev or dev_f > p.init_max_accel_dev:
            raise ValueError(
                f"the vehicle moved during static initialisation (first {ts[-1] - ts[0]:.2f} s): gyro deviation "
                f"{dev_w:.3g} rad/s (limit {p.init_max_gyro_dev}), accelerometer deviation {dev_f:.3g} m/s^2 "
                f"(limit {p.init_max_accel_dev}); keep it still on the pad or raise the limits in LioParams"
            )
        R_WB = attitude_from_up_and_yaw(self._R_BI @ f_mean, p.pad_yaw)
        R_WI = R_WB @ self._R_BI
        bias_acc = np.zeros(3)  # what calibration left is unknown: zero with accel_bias_sigma (and tilt) priors
        p_WI = np.asarray(p.p_WB0) + R_WB @ self._p_BI
        t0 = float(ts[-1])
        self._node = NavEstimate(t0, R_WI, p_WI, np.zeros(3), bias_acc, w_mean.copy())
        self._now = NavEstimate(t0, R_WI, p_WI, np.zeros(3), bias_acc, w_mean.copy())
        self._last_sample = (acc[-1], gyr[-1])
        self._k = 0
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        stamps = gtsam.FixedLagSmootherKeyTimestampMap()
        x0 = pose3(R_WI, p_WI)
        # The pad fixes the origin and the yaw; roll and pitch are as good as the accelerometer bias is small (a
        # horizontal bias b reads as a tilt b / g): their prior is that wide, in the IMU frame's tangent space.
        tilt = p.accel_bias_sigma / p.gravity
        cov = np.zeros((6, 6))  # the pose's tangent space is the IMU frame's: body axes turned by the mounting
        cov[:3, :3] = self._R_BI.T @ np.diag([tilt, tilt, 1e-4]) ** 2 @ self._R_BI
        cov[3:, 3:] = np.eye(3) * 1e-8
        graph.add(gtsam.PriorFactorPose3(X(0), x0, gtsam.noiseModel.Gaussian.Covariance(cov)))
        graph.add(gtsam.PriorFactorVector(V(0), np.zeros(3), gtsam.noiseModel.Isotropic.Sigma(3, 1e-3)))
        bias_sigma = np.r_[np.full(3, p.accel_bias_sigma), np.full(3, p.gyro_bias_sigma)]
        b0 = gtsam.imuBias.ConstantBias(bias_acc, w_mean)
        graph.add(gtsam.PriorFactorConstantBias(B(0), b0, gtsam.noiseModel.Diagonal.Sigmas(bias_sigma)))
        values.insert(X(0), x0)
        values.insert(V(0), np.zeros(3))
        values.insert(B(0), b0)
        for key in (X(0), V(0), B(0)):
            stamps.insert((key, t0))
        self._smoother.update(graph, values, stamps)
        # Frames taken on the pad (checked static above) seed the map at the pad pose.
        for pts_L in self._pad_frames:
            pts_L = pts_L[np.linalg.norm(pts_L, axis=1) >= p.min_range]
            ins = _core.odometry.voxel_downsample(pts_L, p.map_insert_voxel) @ self._R_IL.T + self._p_IL
            self._map.insert(ins @ R_WI.T + p_WI, p_WI)
        self._pad_frames = []

    def _propagate(self, s: NavEstimate, dt: np.ndarray, acc: np.ndarray, gyr: np.ndarray, with_rates: bool = False):
        states, rates = _core.odometry.imu_propagate(
            s.p_W, s.v_W, quat_from_matrix(s.R_WI), s.bias_acc, s.bias_gyr, self._g, dt, acc, gyr
        )
        if with_rates:
            return states, rates
        t = s.t + np.concatenate([[0.0], np.cumsum(dt)])
        return [
            NavEstimate(
                float(t[i]),
                quat_to_matrix(states[i, 6:], normalize=True),
                states[i, :3],
                states[i, 3:6],
                s.bias_acc,
                s.bias_gyr,
            )
            for i in range(len(t))
        ]

    # ---------------------------------------------------------------- LiDAR
    def add_scan(self, t: float, dt: np.ndarray, points_L: np.ndarray) -> Odometry | None:
        """One LiDAR frame: start time t [s], per-point offsets dt (N,) [s], points_L (N, 3) [m]."""
        cpu = time.process_time()  # before the wall clock starts: with the thread pool's workers alive a
        wall = time.perf_counter()  # process-CPU-time read can take tens of microseconds on a busy machine
        if not math.isfinite(t):
            raise ValueError(f"t must be finite [s], got {t!r}")
        pts = np.asarray(points_L)
        d = np.asarray(dt, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 3 or d.shape != (pts.shape[0],):
            raise ValueError(f"points_L must be (N, 3) and dt (N,), got {pts.shape} and {d.shape}")
        if self._node is None:
            # Before initialisation the vehicle is on the pad: the frame is kept to seed the map.
            ok = np.all(np.isfinite(pts), axis=1)
            self._pad_frames.append(np.asarray(pts[ok], dtype=float))
            del self._pad_frames[:-_PAD_FRAMES_KEPT]  # bounded while no IMU sample arrives
            self.dropped_points += int(np.count_nonzero(~ok))
            return None
        # A row with a NaN or inf has a non-finite sum (one BLAS pass instead of an isfinite/all pass over 3N).
        ok = (
            np.isfinite(pts @ np.ones(3, dtype=pts.dtype if pts.dtype.kind == "f" else float))
            & np.isfinite(d)
            & (d >= 0)
        )
        if not ok.all():
            self.dropped_points += int(np.count_nonzero(~ok))
            pts, d = pts[ok], d[ok]
        t_end = t + (float(d.max()) if len(d) else 0.0)
        # a frame ending within _MIN_ADVANCE_S of the newest state (the first one after the initialisation, with a
        # LiDAR clock a few ms off the IMU's) is skipped like one ending before it: a CombinedImuFactor over a few
        # milliseconds is so stiff that GTSAM's elimination finds the bias block indeterminate
        if len(pts) == 0 or t_end <= self._node.t + _MIN_ADVANCE_S:
            self.skipped_scans += 1
            why = "empty frame" if len(pts) == 0 else "frame ends before the state"
            self._consistent = 0 if len(pts) == 0 else self._consistent
            self.diagnostics.append(
                ScanDiagnostics(
                    t_end,
                    0,
                    0,
                    0,
                    (),
                    (),
                    0.0,
                    skipped=why,
                    healthy=len(pts) > 0,
                    reason="no LiDAR constraint: empty frame" if len(pts) == 0 else "",
                )
            )
            return None
        prev = self._node
        knots, pdt, pacc, pgyr = self._imu.pieces(prev.t, t_end)
        states, rates = self._propagate(prev, pdt, pacc, pgyr, with_rates=True)
        # deskewed to the frame end, the airframe's returns dropped, downsampled for the map and for registration
        ins_I, scan_I = _core.odometry.prepare_scan(
            pts,
            t + d,
            knots,
            states,
            rates,
            t_end,
            self._T_BI,
            self._T_BL,
            self.params.min_range,
            self.params.map_insert_voxel,
            self.params.scan_voxel,
            nthreads=self.params.nthreads,
        )
        R_pred, p_pred = quat_to_matrix(states[-1, 6:], normalize=True), states[-1, :3]
        v_pred = states[-1, 3:6]
        k = self._k + 1
        graph = gtsam.NonlinearFactorGraph()
        reg = None
        if len(self._map) == 0:
            R0, p0 = R_pred, p_pred
            skipped = "first frame builds the map"
        else:
            reg = register(self._model, scan_I, R_pred, p_pred)
            R0, p0 = reg.R_WI, reg.p_W
            skipped = ""
            if reg.inliers < 6 * 10:
                skipped = f"too few plane matches ({reg.inliers})"
            elif self.params.tightly_coupled:
                graph.add(self._lidar_factor(X(k), scan_I, reg))
            else:
                graph.add(self._pose_factor(X(k), reg))
        rot_innov = trans_innov = 0.0
        if reg is not None:
            rot_innov = float(np.linalg.norm(_so3_log(R_pred.T @ reg.R_WI)))
            trans_innov = float(np.linalg.norm(reg.p_W - p_pred))
        jump = (
            rot_innov > math.radians(self.params.bias_jump_deg) or trans_innov > self.params.bias_jump_m
        ) and not skipped
        pim = gtsam.PreintegratedCombinedMeasurements(
            self._pim_recovery if jump else self._pim_params, gtsam.imuBias.ConstantBias(prev.bias_acc, prev.bias_gyr)
        )
        for h, a, w in zip(pdt, pacc, pgyr, strict=True):
            pim.integrateMeasurement(a, w, float(h))
        graph.add(gtsam.CombinedImuFactor(X(k - 1), V(k - 1), X(k), V(k), B(k - 1), B(k), pim))
        values = gtsam.Values()
        values.insert(X(k), pose3(R0, p0))
        values.insert(V(k), v_pred)
        values.insert(B(k), gtsam.imuBias.ConstantBias(prev.bias_acc, prev.bias_gyr))
        stamps = gtsam.FixedLagSmootherKeyTimestampMap()
        for key in (X(k), V(k), B(k)):
            stamps.insert((key, t_end))
        self._smoother.update(graph, values, stamps)
        for _ in range(self.params.smoother_iterations - 1):
            self._smoother.update()
        est = self._smoother.calculateEstimate()
        R, pos = pose3_parts(est.atPose3(X(k)))
        bias = est.atConstantBias(B(k))
        self._node = NavEstimate(
            t_end,
            R,
            pos,
            np.asarray(est.atVector(V(k))),
            np.asarray(bias.accelerometer()),
            np.asarray(bias.gyroscope()),
        )
        self._k = k
        healthy, reason = self._health(t_end, skipped, jump, rot_innov, trans_innov)
        # The map grows with this frame, placed at the new estimate.
        self._map.insert(ins_I @ R.T + pos, pos)
        self._catch_up()
        self._imu.prune(t_end - 0.5)
        self.diagnostics.append(
            ScanDiagnostics(
                t_end,
                len(scan_I),
                reg.inliers if reg else 0,
                reg.iterations if reg else 0,
                tuple(float(e) for e in reg.eigenvalues) if reg else (),
                tuple(tuple(float(x) for x in row) for row in reg.degenerate_W) if reg else (),
                (time.perf_counter() - wall) * 1e3,
                cpu_ms=(time.process_time() - cpu) * 1e3,
                skipped=skipped,
                innovation_deg=math.degrees(rot_innov),
                innovation_m=trans_innov,
                healthy=healthy,
                reason=reason,
            )
        )
        if skipped:
            self.skipped_scans += 1
        return self._odometry(self._node)

    def _health(self, t_end: float, skipped: str, jump: bool, rot_innov: float, trans_innov: float) -> tuple[bool, str]:
        """The frame's health verdict: unhealthy when it added no LiDAR constraint, when the IMU's prediction and
        the registration disagree (a bias jump, a bad registration), after a LiDAR gap, and until
        ``health_relock_frames`` consistent frames in a row have followed any of these."""
        p = self.params
        gap = None if self.last_lidar_factor_t is None else t_end - self.last_lidar_factor_t
        if skipped == "first frame builds the map":
            self.last_lidar_factor_t = t_end
            return True, ""
        if skipped:
            self._consistent = 0
            return False, f"no LiDAR constraint: {skipped}"
        self.last_lidar_factor_t = t_end
        if jump:
            self._consistent = 0
            return False, (
                f"IMU prediction and LiDAR registration disagree by {math.degrees(rot_innov):.2f} deg, "
                f"{trans_innov * 100:.1f} cm: re-estimating the IMU biases"
            )
        if gap is not None and gap > p.health_max_lidar_gap_s:
            self._consistent = 0
        self._consistent += 1
        if self._consistent >= p.health_relock_frames:
            return True, ""
        return False, f"re-locking: {self._consistent} of {p.health_relock_frames} consistent LiDAR frames"

    def lidar_gap(self, t: float) -> float | None:
        """Time since the newest LiDAR constraint at ``t`` [s] (None before initialisation)."""
        if self._node is None:
            return None
        return t - (self.last_lidar_factor_t if self.last_lidar_factor_t is not None else self._node.t)

    def _catch_up(self) -> None:
        """The IMU-rate state restarts from the new node and re-integrates the samples after it."""
        node = self._node
        assert node is not None
        ts = np.asarray(self._imu.t)
        if ts[-1] <= node.t:
            self._now = NavEstimate(node.t, node.R_WI, node.p_W, node.v_W, node.bias_acc, node.bias_gyr)
            return
        knots, pdt, pacc, pgyr = self._imu.pieces(node.t, float(ts[-1]))
        self._now = self._propagate(node, pdt, pacc, pgyr)[-1]

    def _pose_factor(self, key: int, reg) -> gtsam.NonlinearFactor:
        evals, evecs, obs = observable_split(reg.H, reg.inliers, self.params)
        noise = min(1.0, self.params.range_sigma / max(reg.residual_sigma, 1e-9)) ** 2  # as in _lidar_factor
        lam = np.where(obs, evals, evals.max() * 1e-12 + 1e-9) * self.params.lidar_information_scale * noise
        info = evecs @ np.diag(lam) @ evecs.T
        return gtsam.PriorFactorPose3(key, pose3(reg.R_WI, reg.p_W), gtsam.noiseModel.Gaussian.Information(info))

    def _lidar_factor(self, key: int, scan_I: np.ndarray, reg) -> gtsam.CustomFactor:
        """Point-to-plane residuals of this frame, re-linearised at every linearisation point (correspondences
        re-found once the pose has moved more than ``refit_distance`` from where they were found): the
        Gauss-Newton form e = L^-T b, de/dxi = L with H = L^T L over the observable directions, so
        |e + L dxi|^2 is the quadratic model of the LiDAR cost."""
        model, params = self._model, self.params
        # Noise-aware: residuals wider than range_sigma (a degraded LiDAR) weaken the factor accordingly.
        s = math.sqrt(params.lidar_information_scale) * min(1.0, params.range_sigma / max(reg.residual_sigma, 1e-9))
        cache: dict[str, Any] = {"planes": reg.planes, "fit_R": reg.R_WI, "fit_p": reg.p_W, "M": None}

        def error(this: gtsam.CustomFactor, values: gtsam.Values, jacobians) -> np.ndarray:
            M = values.atPose3(this.keys()[0]).matrix()
            if cache["M"] is None or not np.array_equal(cache["M"], M):
                R, p = M[:3, :3], M[:3, 3]
                moved = max(np.linalg.norm(p - cache["fit_p"]), np.linalg.norm(R - cache["fit_R"]) * params.map_voxel)
                if moved > params.refit_distance:
                    cache["planes"] = fit_planes(model, scan_I, R, p)
                    cache["fit_R"], cache["fit_p"] = R, p
                terms = plane_terms(model, scan_I, R, p, cache["planes"])
                evals, evecs, obs = observable_split(terms["H"], terms["inliers"], params)
                root = np.sqrt(np.where(obs, evals, 1.0))
                cache["L"] = np.where(obs[:, None], (evecs * root).T, 0.0) * s
                cache["e"] = np.where(obs, (evecs.T @ terms["b"]) / root, 0.0) * s
                cache["M"] = M
            if jacobians is not None:
                jacobians[0] = cache["L"]
            return cache["e"]

        return gtsam.CustomFactor(gtsam.noiseModel.Unit.Create(6), [key], error)

    # ---------------------------------------------------------------- output
    def _odometry(self, s: NavEstimate) -> Odometry:
        R_WB = s.R_WI @ self._R_BI.T
        p_WB = s.p_W - R_WB @ self._p_BI
        w_I = (self._last_sample[1] if self._last_sample is not None else np.zeros(3)) - s.bias_gyr
        w_B = self._R_BI @ w_I
        (wx, wy, wz), (rx, ry, rz) = w_B.tolist(), self._p_BI.tolist()
        v_WB = s.v_W - R_WB @ np.array([wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx])
        return Odometry(t=s.t, p_W=p_WB, v_W=v_WB, q_WB=quat_from_matrix(R_WB), w_B=w_B)

    @property
    def estimate(self) -> NavEstimate | None:
        """The latest IMU-rate state (IMU frame)."""
        return self._now
