"""The visual-inertial odometry core: IMU samples and stereo frames in, body odometry out. No simulator needed.

State: the IMU frame's pose, velocity and biases at each keyframe in GTSAM's ``IncrementalFixedLagSmoother``
(``lag_s``; older states and the landmarks seen only by them are marginalised); ``CombinedImuFactor`` between
consecutive keyframes from every IMU sample (noise from the IMU's datasheet spec, as the LIO's); a landmark per
stereo feature track seen in two keyframes, with a robust ``GenericStereoFactor3D`` per keyframe observation
(rectified left camera at ``T_I_R0``); without a right camera (mono + IMU) a landmark per track whose rays from two
keyframes part by ``mono_min_parallax_deg``, with a ``GenericProjectionFactorCal3_S2`` per keyframe observation,
the scale from the IMU factors. Static initialisation on the pad as the LIO's: gravity direction and
gyroscope bias from the first still second, the pad's position and yaw define the world frame. Between
keyframes the estimate is propagated through each IMU sample (the IMU-rate output).
"""

from __future__ import annotations

import math
import time

import gtsam
import numpy as np
from gtsam.symbol_shorthand import B, L, V, X

from cufund import _core
from cufund.core.messages import Odometry, VioDiagnostics
from cufund.geometry import attitude_from_up_and_yaw, quat_from_matrix, quat_to_matrix

from .boundary import pose3, pose3_parts
from .lio_core import NavEstimate, _ImuBuffer, _so3_log
from .vio_frontend import StereoFrame, StereoFrontEnd, StereoRig
from .vio_params import VioParams

__all__ = ["VioCore"]

_MIN_ADVANCE_S = 0.02
"""A keyframe must come at least this long after the previous one [s] (a shorter IMU factor is too stiff)."""


class VioCore:
    """``add_imu(t, f_I, w_I)`` for every IMU sample, ``add_frame(t, left, right)`` for every stereo frame (after
    the IMU samples up to its stamp). Both return the body ``Odometry`` they produce, or None."""

    def __init__(self, params: VioParams | None = None) -> None:
        self.params = p = params or VioParams()
        self._R_BI = quat_to_matrix(np.asarray(p.imu.q_BI), normalize=True)
        self._p_BI = np.asarray(p.imu.p_BI, dtype=float)
        T_BI = np.eye(4)
        T_BI[:3, :3], T_BI[:3, 3] = self._R_BI, self._p_BI
        self.rig = StereoRig(p)
        self.frontend = StereoFrontEnd(p, self.rig)
        T_I_R0 = np.linalg.inv(T_BI) @ self.rig.T_B_R0
        self._T_I_R0 = T_I_R0
        self._body_P_cam = gtsam.Pose3(T_I_R0)
        K = self.rig.K_rect
        self.mono = self.rig.mono
        self._K = gtsam.Cal3_S2Stereo(K[0, 0], K[1, 1], 0.0, K[0, 2], K[1, 2], max(self.rig.baseline, 1e-3))
        self._K_mono = gtsam.Cal3_S2(K[0, 0], K[1, 1], 0.0, K[0, 2], K[1, 2])
        self._noise = gtsam.noiseModel.Robust.Create(
            gtsam.noiseModel.mEstimator.Huber.Create(p.robust_k), gtsam.noiseModel.Isotropic.Sigma(3, p.pixel_sigma)
        )
        self._noise_mono = gtsam.noiseModel.Robust.Create(
            gtsam.noiseModel.mEstimator.Huber.Create(p.robust_k),
            gtsam.noiseModel.Isotropic.Sigma(2, p.mono_pixel_sigma),
        )
        self._obs: dict[int, list[tuple[int, float, np.ndarray, np.ndarray]]] = {}
        """Monocular: track id -> its keyframe observations (k, t, rectified pixel, T_WR0) before it is a landmark."""
        self._g = np.array([0.0, 0.0, -p.gravity])
        self._landmark_prior = gtsam.noiseModel.Isotropic.Sigma(3, p.landmark_prior_sigma)
        self._pim_params = self._imu_params()
        isam = gtsam.ISAM2Params()
        isam.setRelinearizeThreshold(p.relinearize_threshold)
        isam.relinearizeSkip = 1
        self._smoother = gtsam.IncrementalFixedLagSmoother(p.lag_s, isam)
        self._imu = _ImuBuffer()
        self._node: NavEstimate | None = None
        self._now: NavEstimate | None = None
        self._last_sample: tuple[np.ndarray, np.ndarray] | None = None
        self._k = -1
        self._next_landmark = 0
        self._landmark: dict[int, int] = {}  # track id -> landmark index
        self._pending: dict[int, tuple[int, float, float, float]] = {}  # track id -> (keyframe, uL, uR, v)
        self._in_window: set[int] = set()  # landmark indices the smoother holds
        self._landmark_t: dict[int, float] = {}  # landmark index -> its newest keyframe's stamp
        self._kf_uv: dict[int, np.ndarray] = {}  # track id -> rectified left pixel at the last keyframe
        self._last_frame_t = -math.inf
        self._prev_frame_t: float | None = None
        self._td_num = 0.0
        self._sigma_t = -math.inf
        self._td_den = 0.0
        self.diagnostics: list[VioDiagnostics] = []
        self.skipped_imu = 0
        self.skipped_frames = 0
        self.restarts = 0
        """Times the smoother started again after an ill-posed window."""
        self.restart_reasons: list[str] = []
        self.last_visual_t: float | None = None
        self._good = p.health_relock_frames
        self.reprojection_px = math.nan
        self.imu_chi2 = math.nan
        """Chi-square of the newest keyframe's IMU factor at the smoother's estimate (NaN: none yet)."""
        self._chi2_recent: list[float] = []
        """Median stereo reprojection residual of the newest keyframe's observations [px] (NaN: none yet)."""

    def _imu_params(self) -> gtsam.PreintegrationCombinedParams:
        """The IMU factors' noise from the IMU's datasheet spec (zeros of an ideal part become small densities)."""
        ip = self.params.imu
        acc_w, acc_rw, _ = ip.accel.per_axis(3)
        gyr_w, gyr_rw, _ = ip.gyro.per_axis(3)

        def density(x: np.ndarray, floor: float) -> np.ndarray:
            return np.diag(np.where(np.asarray(x) > 0, x, floor) ** 2)

        pim = gtsam.PreintegrationCombinedParams(self._g)
        pim.setAccelerometerCovariance(density(acc_w, 1e-3))
        pim.setGyroscopeCovariance(density(gyr_w, 1e-4))
        pim.setBiasAccCovariance(density(acc_rw, 1e-4))
        pim.setBiasOmegaCovariance(density(gyr_rw, 1e-5))
        pim.setIntegrationCovariance(np.eye(3) * 1e-10)
        return pim

    @property
    def pim_params(self) -> gtsam.PreintegrationCombinedParams:
        return self._pim_params

    @property
    def initialised(self) -> bool:
        return self._node is not None

    @property
    def time_offset_s(self) -> float:
        """Online camera-IMU time offset estimate [s] (0 while the rotation rate has not changed enough)."""
        return self._td_num / self._td_den if self._td_den > 1e-4 else 0.0

    # ---------------------------------------------------------------- IMU
    def add_imu(self, t: float, f_I: np.ndarray, w_I: np.ndarray) -> Odometry | None:
        f = np.asarray(f_I, dtype=float).reshape(-1)
        w = np.asarray(w_I, dtype=float).reshape(-1)
        if f.shape != (3,) or w.shape != (3,) or not (np.all(np.isfinite(f)) and np.all(np.isfinite(w))):
            raise ValueError(f"f_I and w_I must be 3 finite numbers each, got {f_I!r}, {w_I!r}")
        if not math.isfinite(t):
            raise ValueError(f"t must be finite [s], got {t!r}")
        if self._imu.t and t <= self._imu.t[-1]:
            self.skipped_imu += 1
            return None
        self._imu.t.append(float(t))
        self._imu.acc.append(f)
        self._imu.gyr.append(w)
        if self._node is None:
            self._try_initialise()
            return self._odometry(self._now) if self._now is not None else None
        assert self._now is not None
        if self._last_sample is not None and t > self._now.t:
            acc, gyr = self._last_sample  # the mean of the two samples over the interval between them
            self._now = self.propagate(
                self._now, np.array([t - self._now.t]), 0.5 * (acc + f)[None], 0.5 * (gyr + w)[None]
            )[-1]
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
                f"(limit {p.init_max_accel_dev}); keep it still on the pad or raise the limits in VioParams"
            )
        R_WB = attitude_from_up_and_yaw(self._R_BI @ f_mean, p.pad_yaw)
        R_WI = R_WB @ self._R_BI
        p_WI = np.asarray(p.p_WB0) + R_WB @ self._p_BI
        t0 = float(ts[-1])
        self._node = NavEstimate(t0, R_WI, p_WI, np.zeros(3), np.zeros(3), w_mean.copy())
        self._now = NavEstimate(t0, R_WI, p_WI, np.zeros(3), np.zeros(3), w_mean.copy())
        self._last_sample = (acc[-1], gyr[-1])
        self._k = 0
        graph, values, stamps = gtsam.NonlinearFactorGraph(), gtsam.Values(), gtsam.FixedLagSmootherKeyTimestampMap()
        x0 = pose3(R_WI, p_WI)
        tilt = p.accel_bias_sigma / p.gravity
        cov = np.zeros((6, 6))
        cov[:3, :3] = self._R_BI.T @ np.diag([tilt, tilt, 1e-4]) ** 2 @ self._R_BI
        cov[3:, 3:] = np.eye(3) * 1e-8
        graph.add(gtsam.PriorFactorPose3(X(0), x0, gtsam.noiseModel.Gaussian.Covariance(cov)))
        graph.add(gtsam.PriorFactorVector(V(0), np.zeros(3), gtsam.noiseModel.Isotropic.Sigma(3, 1e-3)))
        b0 = gtsam.imuBias.ConstantBias(np.zeros(3), w_mean)
        sig = np.r_[np.full(3, p.accel_bias_sigma), np.full(3, p.gyro_bias_sigma)]
        graph.add(gtsam.PriorFactorConstantBias(B(0), b0, gtsam.noiseModel.Diagonal.Sigmas(sig)))
        values.insert(X(0), x0)
        values.insert(V(0), np.zeros(3))
        values.insert(B(0), b0)
        for key in (X(0), V(0), B(0)):
            stamps.insert((key, t0))
        self._smoother.update(graph, values, stamps)

    def imu_pieces(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(dt (n,), acc (n, 3), gyr (n, 3)) covering [t0, t1] between the samples there: each piece holds the mean
        of the (linearly interpolated) readings at its two ends, the midpoint rule (a reading held from its own
        stamp on, the zero-order hold, lags the motion by half a sample period); past the newest sample, that
        sample is held."""
        ts = np.asarray(self._imu.t)
        knots = np.concatenate([[t0], ts[(ts > t0) & (ts < t1)], [t1]])
        acc, gyr = np.asarray(self._imu.acc), np.asarray(self._imu.gyr)
        a_k = np.column_stack([np.interp(knots, ts, acc[:, j]) for j in range(3)])
        w_k = np.column_stack([np.interp(knots, ts, gyr[:, j]) for j in range(3)])
        dt = np.diff(knots)
        keep = dt > 0
        return dt[keep], (0.5 * (a_k[1:] + a_k[:-1]))[keep], (0.5 * (w_k[1:] + w_k[:-1]))[keep]

    def propagate(self, s: NavEstimate, dt: np.ndarray, acc: np.ndarray, gyr: np.ndarray) -> list[NavEstimate]:
        """The states after each IMU piece (dt (n,), acc (n, 3), gyr (n, 3)) from s, with s's biases."""
        states, _ = _core.odometry.imu_propagate(
            s.p_W, s.v_W, quat_from_matrix(s.R_WI), s.bias_acc, s.bias_gyr, self._g, dt, acc, gyr
        )
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

    # ---------------------------------------------------------------- frames
    def add_frame(self, t: float, left: np.ndarray, right: np.ndarray | None = None) -> Odometry | None:
        """One stereo frame stamped t [s] (camera clock; ``time_offset_s`` shifts it to the IMU's), or one
        monocular image (``right`` None, with a rig without cam1). A frame not after the previous one is counted
        in ``skipped_frames``; a wrong image is a ValueError."""
        cpu, wall = time.process_time(), time.perf_counter()
        if not math.isfinite(t):
            raise ValueError(f"t must be finite [s], got {t!r}")
        t = float(t) + self.params.time_offset_s
        if t <= self._last_frame_t:
            self.skipped_frames += 1
            return None
        fr = self.frontend.process(t, left, right)  # validates the images
        self._last_frame_t = t
        if self._node is None or not self._imu.t or self._imu.t[-1] < t:
            self._prev_frame_t = t if self._node is not None else None
            return None
        if self.params.estimate_time_offset:
            self._update_time_offset(fr)
        self._prev_frame_t = t
        p = self.params
        uv = fr.uv_left
        common = [i for i, tid in enumerate(fr.ids.tolist()) if tid in self._kf_uv]
        parallax = (
            float(np.mean(np.linalg.norm(uv[common] - np.array([self._kf_uv[fr.ids[i]] for i in common]), axis=1)))
            if common
            else 0.0
        )
        ratio = len(common) / max(len(self._kf_uv), 1)
        keyframe = (
            t - self._node.t >= p.kf_max_interval_s
            or parallax >= p.kf_min_parallax_px
            or ratio < p.kf_min_tracked_ratio
        ) and t - self._node.t >= _MIN_ADVANCE_S
        visual_ok = fr.inliers >= p.health_min_inliers or (
            self.last_visual_t is None and int(fr.stereo.sum() if not self.mono else fr.tracked) >= p.health_min_inliers
        )
        sigma = math.nan
        restarts = self.restarts
        if keyframe:
            sigma = self._add_keyframe(fr)
            self._kf_uv = dict(zip(fr.ids.tolist(), uv, strict=True))
        skipped = "" if visual_ok else f"too few tracked inliers ({fr.inliers})"
        if keyframe and self.restarts > restarts:
            skipped = f"smoother restarted ({self.restart_reasons[-1]})"
        healthy, reason = self._health(t, skipped)
        self.diagnostics.append(
            VioDiagnostics(
                t,
                fr.tracked,
                fr.inliers,
                int(fr.stereo.sum()),
                parallax,
                keyframe,
                len(self._in_window),
                (time.perf_counter() - wall) * 1e3,
                (time.process_time() - cpu) * 1e3,
                self.time_offset_s,
                sigma,
                skipped,
                healthy,
                reason,
            )
        )
        return self._odometry(self._now) if self._now is not None else None

    def _update_time_offset(self, fr: StereoFrame) -> None:
        """Least squares on phi_vis - phi_gyro(0) = td (w(t1) - w(t0)) over frame pairs (the first-order effect
        of an offset on the gyro's rotation between two frames)."""
        if fr.R_cur_prev is None or self._prev_frame_t is None or self._now is None:
            return
        t0, t1 = self._prev_frame_t, fr.t
        ts = np.asarray(self._imu.t)
        if ts[0] > t0 or ts[-1] < t1:
            return
        R_IC = self._T_I_R0[:3, :3]
        phi_vis = _so3_log(R_IC @ fr.R_cur_prev.T @ R_IC.T)
        # the gyro's rotation over [t0, t1] (midpoint rule: a zero-order hold would itself read as an offset)
        pdt, _, pgyr = self.imu_pieces(t0, t1)
        R = np.eye(3)
        for h, w in zip(pdt, pgyr - self._now.bias_gyr, strict=True):
            R = R @ gtsam.Rot3.Expmap(w * h).matrix()
        phi_gyr = _so3_log(R)
        i0 = int(np.searchsorted(ts, t0, side="right")) - 1
        i1 = int(np.searchsorted(ts, t1, side="right")) - 1
        d = np.asarray(self._imu.gyr[i1]) - np.asarray(self._imu.gyr[i0])
        forget = 0.995
        self._td_num = forget * self._td_num + float(d @ (phi_vis - phi_gyr))
        self._td_den = forget * self._td_den + float(d @ d)

    def _add_keyframe(self, fr: StereoFrame) -> float:
        p = self.params
        prev = self._node
        assert prev is not None
        pdt, pacc, pgyr = self.imu_pieces(prev.t, fr.t)
        pred = self.propagate(prev, pdt, pacc, pgyr)[-1]
        k = self._k + 1
        graph, values, stamps = gtsam.NonlinearFactorGraph(), gtsam.Values(), gtsam.FixedLagSmootherKeyTimestampMap()
        pim = gtsam.PreintegratedCombinedMeasurements(
            self._pim_params, gtsam.imuBias.ConstantBias(prev.bias_acc, prev.bias_gyr)
        )
        for h, a, w in zip(pdt, pacc, pgyr, strict=True):
            pim.integrateMeasurement(a, w, float(h))
        imu_factor = gtsam.CombinedImuFactor(X(k - 1), V(k - 1), X(k), V(k), B(k - 1), B(k), pim)
        graph.add(imu_factor)
        values.insert(X(k), pose3(pred.R_WI, pred.p_W))
        values.insert(V(k), pred.v_W)
        values.insert(B(k), gtsam.imuBias.ConstantBias(prev.bias_acc, prev.bias_gyr))
        for key in (X(k), V(k), B(k)):
            stamps.insert((key, fr.t))
        # stereo factors: a landmark per track seen on two keyframes
        T_WI = np.eye(4)
        T_WI[:3, :3], T_WI[:3, 3] = pred.R_WI, pred.p_W
        T_WC = T_WI @ self._T_I_R0
        stereo = fr.stereo
        new_factors: list[gtsam.GenericStereoFactor3D] = []  # re-observations of landmarks (the consistency check)
        pending: dict[int, tuple[int, float, float, float]] = {}
        lo_t = fr.t - p.lag_s + 0.05  # landmarks whose newest keyframe is older leave the window with it
        if self.mono:
            self._mono_factors(fr, k, T_WC, lo_t, graph, values, stamps, new_factors)
            stereo = np.zeros(0, dtype=bool)
        for i in np.flatnonzero(stereo).tolist():
            tid = int(fr.ids[i])
            uL, v = float(fr.uv_left[i, 0]), float(fr.uv_left[i, 1])
            uR = float(fr.uv_right[i, 0])
            meas = gtsam.StereoPoint2(uL, uR, v)
            lid = self._landmark.get(tid)
            if lid is not None and lid in self._in_window and self._landmark_t.get(lid, -math.inf) >= lo_t:
                fac = gtsam.GenericStereoFactor3D(
                    meas, self._noise, X(k), L(lid), self._K, False, False, self._body_P_cam
                )
                graph.add(fac)
                new_factors.append(fac)
                stamps.insert((L(lid), fr.t))
                self._landmark_t[lid] = fr.t
                continue
            old = self._pending.get(tid)
            if old is None:
                pending[tid] = (k, uL, uR, v)
                continue
            kk, ouL, ouR, ov = old
            lid = self._next_landmark
            self._next_landmark += 1
            self._landmark[tid] = lid
            X_C = self.rig.triangulate(np.array([[uL, v]]), np.array([[uR, v]]))[0]
            X_W = T_WC[:3, :3] @ X_C + T_WC[:3, 3]
            values.insert(L(lid), X_W)
            # a weak prior keeps the landmark determined where its stereo factors are not (a point the current
            # estimate puts behind a camera gives a zero factor, GTSAM's cheirality case)
            graph.add(gtsam.PriorFactorPoint3(L(lid), X_W, self._landmark_prior))
            graph.add(
                gtsam.GenericStereoFactor3D(
                    gtsam.StereoPoint2(ouL, ouR, ov),
                    self._noise,
                    X(kk),
                    L(lid),
                    self._K,
                    False,
                    False,
                    self._body_P_cam,
                )
            )
            graph.add(
                gtsam.GenericStereoFactor3D(meas, self._noise, X(k), L(lid), self._K, False, False, self._body_P_cam)
            )
            stamps.insert((L(lid), fr.t))
            self._landmark_t[lid] = fr.t
            self._in_window.add(lid)
        self._pending = pending
        try:
            self._smoother.update(graph, values, stamps)
        except RuntimeError as e:  # an ill-posed window (GTSAM's indeterminate system): start again from here
            self._restart(pred, k, " ".join(str(e).split())[:160] or type(e).__name__)
            return math.nan
        est = self._smoother.calculateEstimate()
        R, pos = pose3_parts(est.atPose3(X(k)))
        bias = est.atConstantBias(B(k))
        self._node = NavEstimate(
            fr.t, R, pos, np.asarray(est.atVector(V(k))), np.asarray(bias.accelerometer()), np.asarray(bias.gyroscope())
        )
        self._k = k
        self.reprojection_px = self._reprojection(new_factors, est)
        if est.exists(X(k - 1)) and est.exists(V(k - 1)) and est.exists(B(k - 1)):
            # the IMU factor's residual at the fused estimate: small when the camera's motion is the IMU's
            self.imu_chi2 = 2.0 * imu_factor.error(est)
            self._chi2_recent = [*self._chi2_recent, self.imu_chi2][-p.health_chi2_keyframes :]
        # landmarks the smoother marginalised
        gone = [lid for lid in self._in_window if self._landmark_t[lid] < lo_t or not est.exists(L(lid))]
        for lid in gone:
            self._in_window.discard(lid)
            del self._landmark_t[lid]
        if gone:
            live = set(self._in_window)
            self._landmark = {tid: lid for tid, lid in self._landmark.items() if lid in live}
        sigma = math.nan
        if (
            self.last_visual_t is not None
            and fr.t - self._sigma_t < p.covariance_every_s
            and fr.inliers >= p.health_min_inliers
        ):
            pass
        else:
            try:
                self._sigma_t = fr.t
                cov = self._smoother.getISAM2().marginalCovariance(X(k))
                sigma = float(math.sqrt(max(np.linalg.eigvalsh(cov[3:, 3:]).max(), 0.0)))
            except RuntimeError:
                pass
        self._catch_up()
        self._imu.prune(fr.t - 0.5)
        return sigma

    def _mono_factors(
        self,
        fr: StereoFrame,
        k: int,
        T_WC: np.ndarray,
        lo_t: float,
        graph: gtsam.NonlinearFactorGraph,
        values: gtsam.Values,
        stamps: gtsam.FixedLagSmootherKeyTimestampMap,
        new_factors: list,
    ) -> None:
        """Monocular keyframe k (its predicted camera pose T_WC): a projection factor per re-observed landmark; a
        track seen from keyframes in the window whose rays part by ``mono_min_parallax_deg`` becomes a landmark,
        triangulated (closest point of the two rays, in front of both cameras within the depth range) from its
        first and this observation, with a factor per keyframe observation and the weak prior. The scale of the
        landmarks and the motion comes from the IMU factors."""
        p = self.params
        K = self.rig.K_rect
        cos_min = math.cos(math.radians(p.mono_min_parallax_deg))
        obs_next: dict[int, list[tuple[int, float, np.ndarray, np.ndarray]]] = {}

        def factor(uv: np.ndarray, kk: int, lid: int) -> gtsam.NonlinearFactor:
            return gtsam.GenericProjectionFactorCal3_S2(
                gtsam.Point2(float(uv[0]), float(uv[1])),
                self._noise_mono,
                X(kk),
                L(lid),
                self._K_mono,
                self._body_P_cam,
            )

        for i, tid in enumerate(fr.ids.tolist()):
            uv = fr.uv_left[i].astype(float)
            lid = self._landmark.get(tid)
            if lid is not None and lid in self._in_window and self._landmark_t.get(lid, -math.inf) >= lo_t:
                fac = factor(uv, k, lid)
                graph.add(fac)
                new_factors.append(fac)
                stamps.insert((L(lid), fr.t))
                self._landmark_t[lid] = fr.t
                continue
            obs = [o for o in self._obs.get(tid, []) if o[1] >= lo_t]
            obs.append((k, fr.t, uv, T_WC))
            _, _, uv0, T0 = obs[0]
            b0 = T0[:3, :3] @ np.array([(uv0[0] - K[0, 2]) / K[0, 0], (uv0[1] - K[1, 2]) / K[1, 1], 1.0])
            b1 = T_WC[:3, :3] @ np.array([(uv[0] - K[0, 2]) / K[0, 0], (uv[1] - K[1, 2]) / K[1, 1], 1.0])
            b0, b1 = b0 / np.linalg.norm(b0), b1 / np.linalg.norm(b1)
            c = float(b0 @ b1)
            if len(obs) < 2 or c > cos_min:
                obs_next[tid] = obs
                continue
            # closest points of the rays c0 + s b0 and c1 + u b1
            c0, c1 = T0[:3, 3], T_WC[:3, 3]
            d = c1 - c0
            den = 1.0 - c * c
            s0 = (d @ b0 - c * (d @ b1)) / den
            s1 = (c * (d @ b0) - d @ b1) / den
            if not (p.min_depth < s0 < p.max_depth and p.min_depth < s1 < p.max_depth):
                obs_next[tid] = obs
                continue
            X_W = 0.5 * (c0 + s0 * b0 + c1 + s1 * b1)
            lid = self._next_landmark
            self._next_landmark += 1
            self._landmark[tid] = lid
            values.insert(L(lid), X_W)
            graph.add(gtsam.PriorFactorPoint3(L(lid), X_W, self._landmark_prior))
            for kk, _, uvk, _ in obs:
                fac = factor(uvk, kk, lid)
                graph.add(fac)
                if kk == k:
                    new_factors.append(fac)
            stamps.insert((L(lid), fr.t))
            self._landmark_t[lid] = fr.t
            self._in_window.add(lid)
        self._obs = obs_next

    @staticmethod
    def _reprojection(factors: list, est: gtsam.Values) -> float:
        """The median stereo reprojection residual [px] of the newest keyframe's observations at the smoother's
        estimate (NaN without any): the visual measurements' disagreement with the IMU-constrained solution."""
        r = [float(np.linalg.norm(f.unwhitenedError(est))) for f in factors if all(est.exists(key) for key in f.keys())]
        return float(np.median(r)) if r else math.nan

    def _restart(self, s: NavEstimate, k: int, why: str) -> None:
        """A new smoother whose first state is ``s`` (the IMU's prediction) with tight priors (1 mrad, 1 mm, 1 cm/s;
        loose ones left the bias indeterminate and restarted every keyframe): the estimate goes on from where it
        was, the landmarks start again."""
        p = self.params
        self.restarts += 1
        self.restart_reasons.append(why)
        isam = gtsam.ISAM2Params()
        isam.setRelinearizeThreshold(p.relinearize_threshold)
        isam.relinearizeSkip = 1
        self._smoother = gtsam.IncrementalFixedLagSmoother(p.lag_s, isam)
        graph, values, stamps = gtsam.NonlinearFactorGraph(), gtsam.Values(), gtsam.FixedLagSmootherKeyTimestampMap()
        x = pose3(s.R_WI, s.p_W)
        b = gtsam.imuBias.ConstantBias(s.bias_acc, s.bias_gyr)
        graph.add(
            gtsam.PriorFactorPose3(X(k), x, gtsam.noiseModel.Diagonal.Sigmas(np.r_[np.full(3, 1e-3), np.full(3, 1e-3)]))
        )
        graph.add(gtsam.PriorFactorVector(V(k), s.v_W, gtsam.noiseModel.Isotropic.Sigma(3, 1e-2)))
        sig = np.r_[np.full(3, p.accel_bias_sigma), np.full(3, p.gyro_bias_sigma)]
        graph.add(gtsam.PriorFactorConstantBias(B(k), b, gtsam.noiseModel.Diagonal.Sigmas(sig)))
        values.insert(X(k), x)
        values.insert(V(k), s.v_W)
        values.insert(B(k), b)
        for key in (X(k), V(k), B(k)):
            stamps.insert((key, s.t))
        self._smoother.update(graph, values, stamps)
        self._node, self._k = s, k
        self._landmark, self._pending, self._in_window, self._landmark_t = {}, {}, set(), {}
        self._obs, self._chi2_recent = {}, []
        self._catch_up()

    def _catch_up(self) -> None:
        node = self._node
        assert node is not None
        ts = np.asarray(self._imu.t)
        if ts[-1] <= node.t:
            self._now = NavEstimate(node.t, node.R_WI, node.p_W, node.v_W, node.bias_acc, node.bias_gyr)
            return
        pdt, pacc, pgyr = self.imu_pieces(node.t, float(ts[-1]))
        self._now = self.propagate(node, pdt, pacc, pgyr)[-1]

    def _health(self, t: float, skipped: str) -> tuple[bool, str]:
        p = self.params
        if skipped:
            self._good = 0
            blind = t - (self.last_visual_t if self.last_visual_t is not None else t)
            return False, f"no visual constraint: {skipped} (IMU only for {blind:.2f} s)"
        gap = None if self.last_visual_t is None else t - self.last_visual_t
        self.last_visual_t = t
        if p.health_max_imu_chi2 is not None and len(self._chi2_recent) >= p.health_chi2_keyframes:
            chi2 = float(np.median(self._chi2_recent))  # one correction (texture back after a gap) is no disagreement
            if chi2 > p.health_max_imu_chi2:
                self._good = 0
                return False, (
                    f"visual and inertial motion disagree: the IMU factors' median chi-square over the last "
                    f"{len(self._chi2_recent)} keyframes is {chi2:.3g} (limit {p.health_max_imu_chi2:g}; a wrong "
                    f"stereo baseline or extrinsic, or drifting tracks)"
                )
        if gap is not None and gap > p.health_max_gap_s:
            self._good = 0
        self._good += 1
        if self._good >= p.health_relock_frames:
            return True, ""
        return False, f"re-locking: {self._good} of {p.health_relock_frames} good frames"

    def visual_gap(self, t: float) -> float | None:
        """Time since the newest frame with a visual constraint [s] (None before initialisation)."""
        if self._node is None:
            return None
        return t - (self.last_visual_t if self.last_visual_t is not None else self._node.t)

    # ---------------------------------------------------------------- output
    def _odometry(self, s: NavEstimate) -> Odometry:
        R_WB = s.R_WI @ self._R_BI.T
        p_WB = s.p_W - R_WB @ self._p_BI
        w_I = (self._last_sample[1] if self._last_sample is not None else np.zeros(3)) - s.bias_gyr
        w_B = self._R_BI @ w_I
        v_WB = s.v_W - R_WB @ np.cross(w_B, self._p_BI)
        return Odometry(t=s.t, p_W=p_WB, v_W=v_WB, q_WB=quat_from_matrix(R_WB), w_B=w_B)

    @property
    def estimate(self) -> NavEstimate | None:
        return self._now
