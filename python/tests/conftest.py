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


@pytest.fixture
def ticks_during():
    """A function run(call) -> (call's result, ticks): `call` runs while another Python thread appends a
    timestamp about every millisecond; ticks are those that fell inside the call. With the GIL held for the
    whole call there would be none."""
    import threading
    import time

    def run(call):
        ticks = []
        done = threading.Event()

        def ticker():
            while not done.is_set():
                ticks.append(time.perf_counter())
                time.sleep(0.001)

        t = threading.Thread(target=ticker)
        t.start()
        try:
            start = time.perf_counter()
            result = call()
            end = time.perf_counter()
        finally:
            done.set()
            t.join()
        return result, [x for x in ticks if start < x < end]

    return run


@pytest.fixture
def ctrl_c():
    """Ctrl-C as an interactive Python has it: SIGINT raises KeyboardInterrupt for the test's duration. A shell
    that runs the suite in the background (`cmd &`, nohup, some batch systems) starts it with SIGINT ignored, and
    Python then installs no handler, so a test of Ctrl-C would see nothing. Its value: the preexec_fn for a child
    Python, which likewise needs SIGINT at its default to install its handler."""
    import signal

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield lambda: signal.signal(signal.SIGINT, signal.SIG_DFL)
    finally:
        signal.signal(signal.SIGINT, previous)
