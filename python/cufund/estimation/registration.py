"""Scan-to-map registration: Gauss-Newton on point-to-plane residuals with degeneracy-aware steps.

The Hessian H (6x6, rotation then translation, right perturbation of T_WI) is split by its eigenvalues: a
direction whose eigenvalue, per inlier and times range_sigma^2, is below ``degeneracy_threshold`` is weakly
observable (a corridor's axis, say). Steps are taken in the observable directions only (Zhang et al.'s solution
remapping), and the LiDAR factor constrains only those, leaving the rest to the IMU.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cufund import _core

from .params import LioParams

__all__ = ["PlaneModel", "Registration", "register", "fit_planes", "plane_terms", "observable_split", "so3_exp"]


def so3_exp(w: np.ndarray) -> np.ndarray:
    t = float(np.linalg.norm(w))
    W = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if t < 1e-8:
        return np.eye(3) + W + 0.5 * W @ W
    return np.eye(3) + np.sin(t) / t * W + (1 - np.cos(t)) / t**2 * W @ W


@dataclass(frozen=True)
class PlaneModel:
    """What the point-to-plane terms need: the map and the fitting settings."""

    map: _core.odometry.VoxelMap
    params: LioParams


def fit_planes(
    model: PlaneModel, points_I: np.ndarray, R_WI: np.ndarray, p_W: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Correspondences: a plane from the map for each point placed by (R_WI, p_W)."""
    p = model.params
    return model.map.fit_planes(
        points_I,
        R_WI,
        p_W,
        neighbours=p.neighbours,
        max_neighbour_distance=p.plane_radius,
        max_plane_rms=p.max_plane_rms,
        nthreads=p.nthreads,
    )


def plane_terms(
    model: PlaneModel,
    points_I: np.ndarray,
    R_WI: np.ndarray,
    p_W: np.ndarray,
    planes: tuple[np.ndarray, np.ndarray] | None = None,
) -> dict:
    """Point-to-plane terms at (R_WI, p_W), against ``planes`` (from :func:`fit_planes`) or re-found ones."""
    p = model.params
    valid, pl = planes if planes is not None else fit_planes(model, points_I, R_WI, p_W)
    return _core.odometry.plane_terms(
        points_I,
        pl,
        valid,
        R_WI,
        p_W,
        max_residual=p.max_residual,
        robust=p.robust,
        robust_scale=p.robust_scale,
        sigma=p.range_sigma,
        nthreads=p.nthreads,
    )


def observable_split(H: np.ndarray, inliers: int, params: LioParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(eigenvalues of H ascending, eigenvectors (columns), observable mask). The normalised eigenvalues
    lambda * range_sigma^2 / inliers are compared with the threshold."""
    evals, evecs = np.linalg.eigh(0.5 * (H + H.T))
    scale = params.range_sigma**2 / max(inliers, 1)
    return evals, evecs, evals * scale > params.degeneracy_threshold


@dataclass(frozen=True)
class Registration:
    R_WI: np.ndarray
    p_W: np.ndarray
    H: np.ndarray
    """Hessian at the solution (information of the pose, rotation then translation) [1/rad^2, 1/m^2]."""
    iterations: int
    inliers: int
    eigenvalues: np.ndarray
    """Normalised eigenvalues (ascending) of H: lambda * range_sigma^2 / inliers."""
    degenerate_W: np.ndarray
    """(D, 6) weakly observable directions [rotation, translation], rotated into the world frame."""
    converged: bool
    planes: tuple[np.ndarray, np.ndarray]
    """The correspondences at the solution (valid, planes), see :func:`fit_planes`."""
    residual_sigma: float = 0.0
    """Robust standard deviation (1.4826 MAD) of the point-to-plane residuals at the solution [m]."""


def register(model: PlaneModel, points_I: np.ndarray, R0: np.ndarray, p0: np.ndarray) -> Registration:
    """Gauss-Newton from (R0, p0): with the correspondences fixed the steps are iterated to ``convergence``;
    correspondences are then re-found (at most ``max_refits`` times) unless the pose ended within
    ``refit_distance`` of where they were found."""
    prm = model.params
    R, p = R0.copy(), p0.copy()
    converged = False
    it = 0
    fits = 0
    while True:
        planes = fit_planes(model, points_I, R, p)
        fits += 1
        R_fit, p_fit = R, p
        for _ in range(prm.max_iterations):
            it += 1
            terms = plane_terms(model, points_I, R, p, planes)
            if terms["inliers"] < 6:
                break
            evals, evecs, obs = observable_split(terms["H"], terms["inliers"], prm)
            V = evecs[:, obs]
            step = -V @ ((V.T @ terms["b"]) / evals[obs])
            p = p + R @ step[3:]
            R = R @ so3_exp(step[:3])
            if np.linalg.norm(step) < prm.convergence:
                break
        moved = max(np.linalg.norm(p - p_fit), np.linalg.norm(R - R_fit) * prm.map_voxel)
        if moved < prm.refit_distance:
            converged = True
            break
        if fits > prm.max_refits:
            break
    terms = plane_terms(model, points_I, R, p, planes)
    evals, evecs, obs = observable_split(terms["H"], terms["inliers"], prm)
    deg = evecs[:, ~obs].T.copy()
    deg[:, :3] = deg[:, :3] @ R.T
    deg[:, 3:] = deg[:, 3:] @ R.T
    r = terms["residual"][terms["valid"].astype(bool)]
    r = r[np.abs(r) <= prm.max_residual]
    sigma = float(1.4826 * np.median(np.abs(r))) if len(r) else 0.0
    return Registration(
        R,
        p,
        terms["H"],
        it,
        int(terms["inliers"]),
        evals * prm.range_sigma**2 / max(int(terms["inliers"]), 1),
        deg,
        converged,
        planes,
        sigma,
    )
