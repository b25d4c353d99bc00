"""Kalibr camchain YAML (``camchain-imucam.yaml``) read and written, so a user's calibrated rig is simulated as it is.

One entry per camera, ``cam0``, ``cam1``, ...::

    cam0:
      camera_model: pinhole
      intrinsics: [fu, fv, pu, pv]
      distortion_model: radtan          # or equidistant (Kalibr's pinhole-equi), none
      distortion_coeffs: [k1, k2, r1, r2]  # equidistant: [k1, k2, k3, k4]
      T_cam_imu: 4x4                    # camera <- IMU: p_cam = T_cam_imu p_imu
      timeshift_cam_imu: 0.0            # t_imu = t_cam + timeshift
      resolution: [width, height]
    cam1:
      T_cn_cnm1: 4x4                    # cam1 <- cam0 (used when cam1 has no T_cam_imu)
      ...

Frames: Kalibr's camera frame is the optical frame O (x right, y down, z forward) and its IMU frame I is the IMU's
(mounted on the body at ``T_BI``; the body frame itself by default). cufund's camera frame C is FLU (x along the
optical axis, y left, z up). Reading converts once::

    T_BC = T_BI · T_cam_imu⁻¹ · T_OC,    T_OC = rotation R_OC = R_COᵀ

and writing inverts it. Kalibr's radtan has 4 coefficients (k3 = 0); a camera with k3 ≠ 0 cannot be written.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from cufund.core.config import load_yaml
from cufund.geometry import Transform, homogeneous, quat_from_matrix

from .camera_models import R_CO, CameraCalibration, CameraIntrinsics, transform_from_matrix

_CAM = re.compile(r"cam(\d+)")
_MODELS = {"radtan": "radtan", "equidistant": "equidistant", "none": "radtan"}


def _T_OC() -> Transform:
    q = quat_from_matrix(R_CO.T)
    return Transform((0.0, 0.0, 0.0), tuple(float(x) for x in q))  # type: ignore[arg-type]


def _numbers(value: Any, n: int, where: str) -> list[float]:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        a = np.full(0, np.nan)
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{where} must be {n} finite numbers, got {value!r}")
    return [float(x) for x in a]


def load_kalibr(path: str | Path, T_BI: Transform | None = None) -> tuple[CameraCalibration, ...]:
    """The cameras of a Kalibr camchain YAML, in order cam0, cam1, ...; ``T_BI``: the IMU's mounting on the
    body (default: the IMU frame is the body frame). Errors name the file, camera and key."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"no Kalibr camchain file at {str(path)!r}")
    # cufund's YAML reader, as for every file it reads: bounded size, nesting and aliases, duplicate keys refused
    # (a ConfigError, a ValueError, naming the file)
    data = load_yaml(path)
    if not isinstance(data, dict) or not data:
        raise ValueError(
            f"{path}: a Kalibr camchain is a mapping cam0: {{...}}, cam1: {{...}}, got {type(data).__name__}"
        )
    ids = []
    for key in data:
        m = _CAM.fullmatch(str(key))
        if m is None:
            raise ValueError(f"{path}: unexpected key {key!r}; a camchain has cam0, cam1, ...")
        ids.append(int(m.group(1)))
    if sorted(ids) != list(range(len(ids))):
        raise ValueError(f"{path}: cameras must be cam0 .. cam{len(ids) - 1} without gaps, got {sorted(data)}")
    T_BI = T_BI or Transform()
    T_OC = _T_OC()
    out: list[CameraCalibration] = []
    T_prev: np.ndarray | None = None
    for i in range(len(ids)):
        where = f"{path}: cam{i}"
        cam = data[f"cam{i}"]
        if not isinstance(cam, dict):
            raise ValueError(f"{where} must be a mapping, got {cam!r}")
        model = cam.get("camera_model", "pinhole")
        if not isinstance(model, str) or model != "pinhole":
            raise ValueError(f"{where}.camera_model must be pinhole (omni, eucm, ds are not simulated), got {model!r}")
        dmodel = cam.get("distortion_model", "none")
        if not isinstance(dmodel, str) or dmodel not in _MODELS:
            raise ValueError(f"{where}.distortion_model must be one of {', '.join(_MODELS)}, got {dmodel!r}")
        n = 4
        coeffs = _numbers(cam.get("distortion_coeffs", [0.0] * n), n, f"{where}.distortion_coeffs")
        fu, fv, pu, pv = _numbers(cam.get("intrinsics"), 4, f"{where}.intrinsics ([fu, fv, pu, pv])")
        if "resolution" not in cam:
            raise ValueError(f"{where}: missing key 'resolution' ([width, height])")
        w, h = _numbers(cam["resolution"], 2, f"{where}.resolution ([width, height])")
        try:
            K = CameraIntrinsics(w, h, fu, fv, pu, pv, tuple(coeffs), _MODELS[dmodel])  # type: ignore[arg-type]
        except ValueError as e:
            raise ValueError(f"{where}: {e}") from None
        if "T_cam_imu" in cam:
            T_cam_imu = homogeneous(transform_from_matrix(cam["T_cam_imu"], f"{where}.T_cam_imu"))
        elif "T_cn_cnm1" in cam and T_prev is not None:
            T_cam_imu = homogeneous(transform_from_matrix(cam["T_cn_cnm1"], f"{where}.T_cn_cnm1")) @ T_prev
        else:
            raise ValueError(f"{where}: missing key 'T_cam_imu' (or T_cn_cnm1 after cam0)")
        T_prev = T_cam_imu
        ts = cam.get("timeshift_cam_imu", 0.0)
        if isinstance(ts, bool) or not isinstance(ts, (int, float)) or not np.isfinite(ts):
            raise ValueError(f"{where}.timeshift_cam_imu must be a finite number [s], got {ts!r}")
        T_IO = transform_from_matrix(np.linalg.inv(T_cam_imu), f"{where}.T_cam_imu")
        out.append(CameraCalibration(K, T_BI @ T_IO @ T_OC, float(ts), f"cam{i}"))
    return tuple(out)


def dump_kalibr(cams: Sequence[CameraCalibration], path: str | Path, T_BI: Transform | None = None) -> None:
    """Writes ``cams`` as a Kalibr camchain YAML (``T_BI`` as in :func:`load_kalibr`)."""
    if not cams or not all(isinstance(c, CameraCalibration) for c in cams):
        raise ValueError("cams must be a non-empty sequence of CameraCalibration")
    T_IB = (T_BI or Transform()).inverse()
    T_CO = _T_OC().inverse()
    data: dict[str, Any] = {}
    prev: np.ndarray | None = None
    for i, cal in enumerate(cams):
        K = cal.intrinsics
        if K.distortion_model == "radtan":
            if K.distortion[4] != 0.0:
                raise ValueError(f"cam{i}: Kalibr's radtan has no k3, got k3 = {K.distortion[4]}")
            coeffs = list(K.distortion[:4])
        else:
            coeffs = list(K.distortion)
        T_cam_imu = np.linalg.inv(homogeneous(T_IB @ cal.T_BC @ T_CO))
        entry: dict[str, Any] = {
            "camera_model": "pinhole",
            "intrinsics": [K.fx, K.fy, K.cx, K.cy],
            "distortion_model": K.distortion_model,
            "distortion_coeffs": coeffs,
            "T_cam_imu": T_cam_imu.tolist(),
            "timeshift_cam_imu": cal.timeshift_s,
            "resolution": [K.width, K.height],
        }
        if prev is not None:
            entry["T_cn_cnm1"] = (T_cam_imu @ np.linalg.inv(prev)).tolist()
        if len(cams) > 1:
            entry["cam_overlaps"] = [j for j in range(len(cams)) if j != i]
        entry["rostopic"] = f"/cam{i}/image_raw"
        prev = T_cam_imu
        data[f"cam{i}"] = entry
    Path(path).write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
