"""Shared fixtures: the repository, the CLI binary, the real meshes of ../shared/scenes."""

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import raysift

REPO = Path(__file__).resolve().parents[3]
BUNNY = REPO / "assets" / "bunny.ply.gz"


def skip(reason):
    """Skips with the reason printed (pytest -s shows it; -rs lists it at the end)."""
    print(f"SKIPPED: {reason}")
    pytest.skip(reason)


def find_shared_scenes():
    """`shared/scenes` beside the checkout (or $RAYSIFT_SCENES), as the Rust tests find it."""
    env = os.environ.get("RAYSIFT_SCENES")
    if env and Path(env).is_dir():
        return Path(env)
    for a in [REPO, *REPO.parents]:
        p = a / "shared" / "scenes"
        if p.is_dir():
            return p
    return None


@pytest.fixture(scope="session")
def scenes_dir():
    d = find_shared_scenes()
    if d is None:
        skip("../shared/scenes not found (CI has it)")
    return d


@pytest.fixture(scope="session")
def cli():
    """The `raysift` command built from this checkout (`cargo build --release -p raysift-cli`);
    CI builds it before pytest, so there its absence fails."""
    exe = Path(os.environ.get("RAYSIFT_CLI", REPO / "target" / "release" / "raysift"))
    if not exe.is_file():
        msg = f"{exe} not found: run `cargo build --release -p raysift-cli` first"
        if os.environ.get("CI"):
            pytest.fail(msg)
        skip(msg)

    def run(*args):
        r = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True)
        if r.returncode != 0:
            raise AssertionError(f"raysift {' '.join(map(str, args))}: {r.stderr.strip()}")
        return r

    return run


def global_prims(scene, hits):
    """Scene-wide primitive ids (the CLI's `prim`) from cast_rays' per-mesh ids."""
    geom = hits["geometry_ids"].reshape(-1)
    local = hits["primitive_ids"].reshape(-1)
    offsets = scene.primitive_offsets
    miss = local == raysift.MISS
    out = offsets[np.where(miss, 0, geom)] + local
    out[miss] = raysift.MISS
    return out


def assert_bits_equal(name, got, want):
    got = np.ascontiguousarray(got).reshape(-1)
    want = np.ascontiguousarray(want).reshape(-1)
    assert got.shape == want.shape, f"{name}: shape {got.shape} vs {want.shape}"
    if got.dtype.kind == "f":
        got, want = got.view(np.uint32), want.view(np.uint32)
    bad = np.nonzero(got != want)[0]
    assert len(bad) == 0, f"{name}: {len(bad)} differ, first at {bad[0]}: {got[bad[0]]} vs {want[bad[0]]}"
