"""`cufund dataset --randomisation FILE`: a YAML of randomisation ranges overrides the defaults (the camera drawn
where the file says), and a bad file is refused naming the key, before anything is rendered."""

from __future__ import annotations

import json

import numpy as np

from cufund.apps.cli import main


def _dataset(tmp_path, text: str | None, name: str = "ds") -> tuple[int, object]:
    args = ["dataset", "forest", "--out", str(tmp_path / name), "--frames", "4", "--seed", "5", "--scatter", "6"]
    args += ["--classes", "person,car", "--width", "64", "--height", "48", "--hfov-deg", "36", "--no-progress"]
    if text is not None:
        (tmp_path / "r.yaml").write_text(text)
        args += ["--randomisation", str(tmp_path / "r.yaml")]
    return main(args), tmp_path / name


def test_ranges_from_the_file_place_the_camera(tmp_path):
    rc, out = _dataset(tmp_path, "height_m: [11.0, 11.5]\ndistance_m: [9.0, 10.0]\nlook_jitter_deg: [0, 0]\n")
    assert rc == 0
    meta = json.loads((out / "dataset.json").read_text())
    assert meta["randomisation"]["height_m"] == [11.0, 11.5]
    assert meta["camera"]["width"] == 64
    looking = [f for f in meta["frames"] if not f["negative"]]
    assert looking, "every frame drawn as a negative: nothing checked"
    for f in meta["frames"]:
        assert 11.0 <= f["p_W"][2] <= 11.5
    # the defaults put the camera 0.4-4 m up: the file, not the default, placed it
    rc, out = _dataset(tmp_path, None, "default")
    assert rc == 0
    zs = [f["p_W"][2] for f in json.loads((out / "dataset.json").read_text())["frames"]]
    assert np.all(np.array(zs) <= 4.0)


def test_a_bad_file_is_refused_naming_the_key(tmp_path, capsys):
    cases = {
        "hieght_m: [1, 2]\n": "hieght_m",
        "height_m: [5, 2]\n": "randomisation.height_m",
        "height_m: 3\n": "randomisation.height_m",
        "- 1\n- 2\n": "randomisation must be a mapping",
    }
    for text, named in cases.items():
        rc, out = _dataset(tmp_path, text, "bad")
        assert rc == 2
        assert named in capsys.readouterr().err
        assert not (out / "images").exists()
