"""Shared fixtures: the repository root, the CLI binary of the same build, small bundled data."""

import os
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def root():
    return ROOT


@pytest.fixture(scope="session")
def cli():
    """The rangebayes binary built with the module (RANGEBAYES_CLI, else build/ci/apps/rangebayes)."""
    path = pathlib.Path(os.environ.get("RANGEBAYES_CLI", ROOT / "build" / "ci" / "apps" / "rangebayes"))
    if not path.is_file():
        pytest.fail(f"the rangebayes CLI is not at {path}; build it or set RANGEBAYES_CLI")
    return path


@pytest.fixture(scope="session")
def trim_star():
    return ROOT / "tests" / "data" / "meshes" / "trim-star_noisy_gauss_n3.obj"


@pytest.fixture(scope="session")
def recording_dir():
    return ROOT / "recordings" / "synth_planes_320x240"
