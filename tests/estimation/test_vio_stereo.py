"""The VIO's stereo matching against images of known disparity, its default rig on a scenario without cameras
(``cufund run tunnel --set estimator.kind=vio``) and ``cameras: mono`` from a scenario."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from cufund.core.config import ConfigError
from cufund.estimation.vio_frontend import StereoFrontEnd, StereoRig
from cufund.estimation.vio_params import VioCamera, VioParams
from cufund.geometry import Transform

F, B = 400.0, 0.11
CAM0 = VioCamera(640, 480, F, F, 319.5, 239.5, T_BC=Transform((0.1, B / 2, 0.0)))
CAM1 = VioCamera(640, 480, F, F, 319.5, 239.5, T_BC=Transform((0.1, -B / 2, 0.0)))


def _texture(seed: int, shape=(480, 900)) -> np.ndarray:
    """Low-contrast blotchy noise (the tunnel walls' kind of texture): smoothed Gaussian noise around grey 60."""
    rng = np.random.default_rng(seed)
    img = cv2.GaussianBlur(rng.normal(0.0, 1.0, shape), (0, 0), 1.2)
    return np.clip(60 + 12 * img / img.std(), 0, 255).astype(np.uint8)


def _pair(texture: np.ndarray, disparity: int) -> tuple[np.ndarray, np.ndarray]:
    """A fronto-parallel plane at depth F B / disparity: the right image is the left one shifted left by the
    disparity: the right pixel u - d sees what the left pixel u sees (both cut from one wider texture)."""
    return texture[:, :640].copy(), texture[:, disparity : disparity + 640].copy()


@pytest.mark.parametrize("depth", [2.0, 0.5, 0.3])
def test_stereo_matches_have_the_planes_disparity(depth):
    """A textured plane at 2, 0.5 and 0.3 m (disparity 22, 88 and 147 px, the last two beyond what KLT finds from a
    zero-disparity guess): the stereo matches' disparities are the plane's within 0.3 px, and most features get
    one (KLT alone left most without a match and some with another patch's disparity, in the tunnel's frames)."""
    d = int(round(F * B / depth))
    left, right = _pair(_texture(3), d)
    fe = StereoFrontEnd(VioParams(cam0=CAM0, cam1=CAM1), StereoRig(VioParams(cam0=CAM0, cam1=CAM1)))
    fr = fe.process(0.0, left, right)
    st = fr.stereo
    visible = fr.uv_left[:, 0] >= d + 8  # the plane's points the right camera sees
    disp = fr.uv_left[st, 0] - fr.uv_right[st, 0]
    assert np.abs(disp - d).max() < 0.3
    assert np.count_nonzero(st) >= 0.8 * np.count_nonzero(visible)


def test_a_repetitive_texture_gives_no_wrong_stereo_match():
    """Vertical stripes of a 12 px period (a brick course, a grating) on a plane at 40 px disparity, each camera with
    its own pixel noise: every match along the row is about as good as the true one, so a match reported must be the
    true one (within 0.3 px) or none. Without the ``stereo_ncc_margin`` check wrong ones come (the texture is
    ambiguous; with one noise draw in both images, as before, the true match scored 1.0 and no check was needed)."""
    u = np.arange(900)
    stripes = 60 + 40 * np.sign(np.sin(2 * np.pi * u / 12.0))

    def image(seed: int) -> np.ndarray:
        rng = np.random.default_rng(seed)
        tex = np.clip(stripes[None, :] + rng.normal(0, 1.0, (480, 900)), 0, 255).astype(np.uint8)
        tex[::40] = 20  # horizontal mortar lines: corners for the detector
        return tex

    left, right = image(0)[:, :640].copy(), image(1)[:, 40:680].copy()
    wrong = []
    for margin in (VioParams.stereo_ncc_margin, 1e-9):
        params = VioParams(cam0=CAM0, cam1=CAM1, stereo_ncc_margin=margin)
        fr = StereoFrontEnd(params, StereoRig(params)).process(0.0, left, right)
        disp = fr.uv_left[fr.stereo, 0] - fr.uv_right[fr.stereo, 0]
        wrong.append(np.round(disp[np.abs(disp - 40) >= 0.3], 1))
    assert len(wrong[0]) == 0, wrong[0]
    assert len(wrong[1]) > 5, wrong[1]


def test_stereo_search_params_are_checked():
    for kw, match in (
        ({"stereo_patch_px": 10}, "stereo_patch_px must be odd"),
        ({"stereo_patch_px": 1}, "stereo_patch_px must be an integer >= 3"),
        ({"stereo_min_ncc": 1.5}, "stereo_min_ncc must be at most 1"),
        ({"stereo_fb_px": 0.0}, "stereo_fb_px"),
        ({"cameras": "trinocular"}, "cameras must be 'stereo' or 'mono'"),
    ):
        with pytest.raises(ConfigError, match=match):
            VioParams(**kw)
    assert VioParams(cameras="mono").cam1 is None and VioParams(cam1=None).cameras == "mono"


def _components(scenario: str, overrides: list[str]):
    from cufund.scenarios.build import build_simulation
    from cufund.scenarios.schema import load_scenario

    return build_simulation(load_scenario(scenario, overrides))


def test_tunnel_on_vio_mounts_the_default_rig():
    """``cufund run tunnel --set estimator.kind=vio``: the tunnel states no camera, so the vio kind mounts the
    stereo_camera kind's default rig (as sensors.stereo, triggered on the IMU) and reads its two topics; the
    LiDAR stays (the frame detector's). The tunnel on its LIO renders no image."""
    from cufund.estimation.vio_estimator import VioEstimator
    from cufund.sensors.camera_component import CameraRigComponent

    built = _components("tunnel", ["estimator.kind=vio"])
    comps = built.simulator.components
    rigs = [c for c in comps if isinstance(c, CameraRigComponent)]
    vio = [c for c in comps if isinstance(c, VioEstimator)]
    assert len(rigs) == 1 and len(vio) == 1
    assert vio[0].inputs[1:] == ("/sensors/cam0/image", "/sensors/cam1/image")
    assert vio[0].params.cam1 is not None and vio[0].params.cam1.T_BC.t[1] < 0 < vio[0].params.cam0.T_BC.t[1]
    assert "sensors.stereo" in built.context.world_readers and "estimator" not in built.context.world_readers
    assert "/sensors/lidar" in {str(s.topic) for s in built.config.sensors.values()}
    lio = _components("tunnel", [])
    comps = lio.simulator.components
    assert not [c for c in comps if isinstance(c, CameraRigComponent)]


def test_mono_from_a_scenario():
    """``estimator: {kind: vio, cameras: mono}``: the VIO reads the rig's left camera alone (its topic only), the
    stated calibration of cam0; giving cam1 is still the scenario's business."""
    from cufund.estimation.vio_estimator import VioEstimator

    built = _components("square_vio", ["estimator.cameras=mono"])
    comps = built.simulator.components
    (vio,) = [c for c in comps if isinstance(c, VioEstimator)]
    assert vio.inputs[1:] == ("/sensors/cam0/image",) and vio.params.cam1 is None and vio.core.mono
    assert vio.params.cam0.T_BC.t[1] == pytest.approx(0.055)
    with pytest.raises(ConfigError, match="estimator.cam0: the VIO takes it from the scenario"):
        _components("square_vio", ["estimator.cameras=mono", "estimator.cam0.fx=300"])


def test_mono_estimator_flies_on_the_left_images_alone():
    """The component with ``cameras: mono`` takes the left camera's images alone (no right topic, nothing to pair)
    and gives IMU-rate odometry that follows the synthetic flight's truth (within 5 cm over 4 s)."""
    import math

    from cufund.core.messages import CameraImage, Imu
    from cufund.estimation.vio_estimator import VioEstimator
    from cufund.estimation.vio_synthetic import TexturedRoom, hover_then, synthesize

    c0 = VioCamera(320, 240, 200.0, 200.0, 159.5, 119.5, T_BC=Transform((0.1, 0.05, 0.0)))
    c1 = VioCamera(320, 240, 200.0, 200.0, 159.5, 119.5, T_BC=Transform((0.1, -0.05, 0.0)))
    traj = hover_then(
        lambda t: (
            (0.8 * math.sin(0.9 * t), 0.5 * math.sin(0.7 * t), 0.2 * math.sin(1.3 * t), 0.6 * math.sin(0.6 * t))
            + (0.1 * math.sin(1.1 * t), 0.1 * math.sin(1.4 * t))
        ),
        (0.0, 0.0, 1.5),
    )
    run = synthesize(traj, 4.0, c0, c1, TexturedRoom(seed=1), accel_noise=7e-4, gyro_noise=5e-5)
    est = VioEstimator(VioParams(cam0=c0, cameras="mono", p_WB0=(0.0, 0.0, 1.5)), right_topic=None)
    assert len(est.inputs) == 2 and est.right_topic is None
    out = est.feed([CameraImage(t, a) for t, a, _ in run.frames], [], [Imu(t, f, w) for t, f, w in run.imu])
    assert len(out) >= len(run.imu) - 200 - 2 and sum(d.keyframe for d in est.core.diagnostics) > 10
    t = np.array([o.t for o in out])
    p = np.array([o.p_W for o in out])
    i = np.searchsorted(run.truth_t, t - 1e-9)
    assert np.linalg.norm(p - run.truth_p[i], axis=1).max() < 0.05
