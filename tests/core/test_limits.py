"""cufund.core.limits and the YAML loader's bounds (issue 11): hostile or mistyped files fail fast."""

from __future__ import annotations

import time

import pytest

import cufund.core.limits
from cufund import ConfigError
from cufund.core.config import load_yaml

LAUGHS = "\n".join(
    ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    + [f"{c}: &{c} [{', '.join(['*' + p] * 9)}]" for p, c in zip("abcdefgh", "bcdefghi", strict=True)]
)


def test_billion_laughs_fails_fast_with_config_error(tmp_path):
    path = tmp_path / "laughs.yaml"
    path.write_text(LAUGHS)  # 9**9 = 387 million strings once expanded, from under 1 KB
    assert path.stat().st_size < 1024
    start = time.process_time()
    with pytest.raises(ConfigError, match=r"laughs.yaml: more than yaml_max_nodes = 1000000 values"):
        load_yaml(path)
    assert time.process_time() - start < 5.0  # a bound on work, not a timing test: unbounded takes minutes


def test_self_referencing_alias_is_rejected(tmp_path):
    path = tmp_path / "self.yaml"
    path.write_text("vehicle: &v\n  mass: 1.0\n  again: *v\n")
    with pytest.raises(ConfigError, match=r"self.yaml: an alias refers to a value that contains it \(line \d+\)"):
        load_yaml(path)


@pytest.mark.parametrize("depth", [65, 5000])
def test_deep_nesting_is_a_config_error_not_a_recursion_error(tmp_path, depth):
    path = tmp_path / "deep.yaml"
    path.write_text("[" * depth + "]" * depth)
    with pytest.raises(ConfigError, match="nesting deeper than yaml_max_depth = 64"):
        load_yaml(path)


def test_ordinary_aliases_and_merge_keys_still_load(tmp_path):
    path = tmp_path / "ok.yaml"
    path.write_text("base: &b {mass: 1.0, arm_length: 0.2}\nvehicle:\n  <<: *b\n  mass: 2.0\nlist: [*b, *b]\n")
    data = load_yaml(path)
    assert data["vehicle"] == {"mass": 2.0, "arm_length": 0.2}
    assert data["list"] == [{"mass": 1.0, "arm_length": 0.2}] * 2


def test_alias_count_and_file_size_limits_are_configurable(tmp_path):
    path = tmp_path / "aliases.yaml"
    path.write_text("a: &a 1\nb: [" + ", ".join(["*a"] * 20) + "]\n")
    assert load_yaml(path)["b"] == [1] * 20
    with cufund.core.limits.override(yaml_max_aliases=10):
        with pytest.raises(ConfigError, match="more than yaml_max_aliases = 10 alias uses"):
            load_yaml(path)
    with cufund.core.limits.override(yaml_max_bytes=16):
        with pytest.raises(ConfigError, match=r"aliases.yaml: the file is \d+ bytes, more than yaml_max_bytes = 16"):
            load_yaml(path)
    assert load_yaml(path)["a"] == 1  # restored


def test_non_utf8_file_is_a_config_error(tmp_path):
    path = tmp_path / "latin1.yaml"
    path.write_bytes(b"name: caf\xe9\n")
    with pytest.raises(ConfigError, match="latin1.yaml: not UTF-8 text"):
        load_yaml(path)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"grid_max_voxel": 10}, "unknown limit 'grid_max_voxel'"),
        ({"grid_max_voxels": 0}, "grid_max_voxels must be an integer >= 1, got 0"),
        ({"batch_max_size": 2.5}, "batch_max_size must be an integer >= 1, got 2.5"),
        ({"yaml_max_depth": True}, "yaml_max_depth must be an integer >= 1, got True"),
        ({"step_max_substeps": 10**10}, "step_max_substeps must be at most 1e9"),
    ],
)
def test_configure_validates_its_arguments(changes, message):
    before = cufund.core.limits.current()
    with pytest.raises(ConfigError, match=message):
        cufund.core.limits.configure(**changes)
    assert cufund.core.limits.current() == before
