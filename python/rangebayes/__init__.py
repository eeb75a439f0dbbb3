"""rangebayes: stereo range scanning to clean, compact 3D meshes (Bayesian smoothing and decimation).

The C++ library from Python. Entry points: read_mesh / write_mesh, smooth (the same defaults and result as
`rangebayes smooth`), decimate / decimate_animated, match / stereo / triangulate, read_rig / write_rig,
read_noise_model / write_noise_model, calibrate_rig / calibrate_noise / check_noise_model,
read_middlebury_scene / read_disparity / evaluate_disparity, synth, open_recording / replay, learn_prior,
fuse (many scans, one model), render / write_png (pictures of meshes). Every library error is a
rangebayes.Error (a RuntimeError) with the library's message. Open3D interop: to_open3d / from_open3d (when
open3d is installed). Long calls release the GIL. Meshes, depth frames, rigs, noise models, learned priors
and the summaries of smooth, decimate and evaluate_disparity pickle (multiprocessing, copy.deepcopy).

Importing sets glibc's malloc as the `rangebayes` CLI does, so that buffers freed by one call are reused by the
next instead of being faulted in again: blocks up to 32 MiB come from the heap and up to 256 MiB of free heap
stay mapped. A GLIBC_TUNABLES environment variable that sets any glibc.malloc tunable is left as it is.
"""

from ._rangebayes import *  # noqa: F401,F403
from ._rangebayes import Error, Mesh, NoisyMesh, __doc__ as _ext_doc  # noqa: F401
from ._open3d import from_open3d, to_open3d  # noqa: F401

__version__ = "0.1.0"
