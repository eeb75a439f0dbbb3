"""Pickling (multiprocessing, copy.deepcopy) of the values the module returns: every public attribute comes back
equal, brief_report() prints the same, and a state from another version of the module is refused by name."""

import copy
import multiprocessing
import pickle

import numpy as np
import pytest

import rangebayes as rb


def same(a, b, path):
    """Asserts a and b equal attribute by attribute (NaN equal to NaN), recursing into bound objects."""
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype == b.dtype, path
        np.testing.assert_array_equal(a, b, err_msg=path)
    elif isinstance(a, (list, tuple)):
        assert type(a) is type(b) and len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            same(x, y, f"{path}[{i}]")
    elif isinstance(a, float):
        assert (np.isnan(a) and np.isnan(b)) or a == b, f"{path}: {a} != {b}"
    elif a is None or isinstance(a, (bool, int, str)):
        assert a == b, f"{path}: {a!r} != {b!r}"
    else:
        assert type(a) is type(b), path
        names = [n for n in dir(a) if not n.startswith("_") and not callable(getattr(a, n))]
        assert names, f"{path}: {type(a).__name__} has no attributes to compare"
        for n in names:
            same(getattr(a, n), getattr(b, n), f"{path}.{n}")
        if hasattr(a, "brief_report"):
            assert a.brief_report() == b.brief_report(), path


@pytest.fixture(scope="module")
def values(recording_dir, trim_star):
    """One of each picklable value, made by the library itself."""
    rec = rb.open_recording(str(recording_dir))
    frame = rb.stereo(rec.rig, rec[0].left, rec[0].right)
    raw = rb.triangulate(frame)
    smoothed, smooth_summary = rb.smooth(raw, tolerance="fast")
    generic, generic_summary = rb.smooth(rb.read_mesh(str(trim_star)), tolerance="fast")
    decimated, decimate_summary = rb.decimate(smoothed, target_faces=400)
    gt = rb.synth(scene="planes", width=160, height=120, frames=1)
    d = gt.disparity_px + np.float32(0.3)
    prior = rb.LearnedPrior()
    prior.num_knots, prior.theta, prior.noise_kind = 3, np.sqrt(np.array([0.0, 1.0, 4.0]) + 1e-4), "normal"
    model = rb.DisparityNoiseModel()
    model.form, model.floor_px, model.matcher = "learned", 0.2, "sgbm"
    return {
        "rig": rec.rig,
        "intrinsics": frame.intrinsics,
        "depth frame": frame,
        "noisy mesh": raw,
        "mesh": smoothed,
        "smooth summary (organized)": smooth_summary,
        "smooth summary (generic, estimated k)": generic_summary,
        "generic mesh": generic,
        "decimated mesh": decimated,
        "decimate summary": decimate_summary,
        "corner normals": decimated.corner_normals,
        "disparity evaluation": rb.evaluate_disparity(d, gt.disparity_px),
        "learned prior": prior,
        "noise model": model,
    }


def test_every_value_round_trips(values):
    assert values["noisy mesh"].has_covariance and values["noisy mesh"].pixel.shape[0] > 0
    assert values["smooth summary (generic, estimated k)"].noise_model.generic.estimated
    assert values["smooth summary (organized)"].noise_model.from_file
    for name, value in values.items():
        for back in (pickle.loads(pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)), copy.deepcopy(value)):
            same(value, back, name)
    # The copies own their storage.
    mesh = values["mesh"]
    back = pickle.loads(pickle.dumps(mesh))
    back.V[0, 0] += 1.0
    assert back.V[0, 0] != mesh.V[0, 0]


def smooth_in_worker(path):
    return rb.smooth(rb.read_mesh(path), tolerance="fast")


def test_results_come_back_from_worker_processes(trim_star):
    """The researcher's batch: smooth() in a pool of processes; results travel back pickled."""
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        results = pool.map(smooth_in_worker, [str(trim_star)] * 2)
    here, here_summary = smooth_in_worker(str(trim_star))
    for mesh, summary in results:
        np.testing.assert_array_equal(mesh.V, here.V)
        assert summary.iterations == here_summary.iterations and summary.termination == here_summary.termination


def test_images_that_came_through_pickle_are_accepted(recording_dir):
    """An array sent to a worker process carries its own dtype instance; stereo() refused it ("expected dtype
    uint8, uint16, float32 or float64, got uint8")."""
    rec = rb.open_recording(str(recording_dir))
    left, right = (pickle.loads(pickle.dumps(image)) for image in (rec[0].left, rec[0].right))
    np.testing.assert_array_equal(rb.stereo(rec.rig, left, right).disparity_px,
                                  rb.stereo(rec.rig, rec[0].left, rec[0].right).disparity_px)
    with pytest.raises(TypeError, match="got >f4"):
        rb.stereo(rec.rig, left.astype(">f4"), right.astype(">f4"))


def test_a_state_from_another_version_is_refused_by_name():
    state = rb.CameraIntrinsics().__getstate__()
    state[0]["focal_px"] = state[0].pop("fx_px")
    fresh = rb.CameraIntrinsics.__new__(rb.CameraIntrinsics)
    with pytest.raises(ValueError, match="missing fx_px unknown focal_px"):
        fresh.__setstate__(state)
    with pytest.raises(ValueError, match="not a state this module wrote"):
        rb.Mesh.__new__(rb.Mesh).__setstate__((1, 2))
    # A pickled mesh is checked as Mesh(...) checks its arrays.
    with pytest.raises(ValueError, match="outside"):
        rb.Mesh.__new__(rb.Mesh).__setstate__((np.zeros((3, 3)), np.array([[0, 1, 5]], np.int32), None))


def test_objects_that_hold_files_or_streams_say_they_do_not_pickle(recording_dir):
    with pytest.raises(TypeError, match="pickle"):
        pickle.dumps(rb.open_recording(str(recording_dir)))
