# Type stub of the rangebayes module (for editors; the docstrings at run time hold units and contracts).
import os
from typing import Any, Callable, Iterator, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str

ArrayLike = npt.ArrayLike
Progress = Callable[[float, str], Any]
StrPath = Union[str, os.PathLike[str]]  # file and folder arguments

class Error(RuntimeError): ...

class Mesh:
    V: npt.NDArray[np.float64]  # (n, 3), view of the C++ storage; assignment copies
    F: npt.NDArray[np.int32]  # (m, 3)
    N: npt.NDArray[np.float64]  # (n, 3) or (0, 3)
    def __init__(self, V: ArrayLike, F: ArrayLike, N: Optional[ArrayLike] = ...) -> None: ...
    @property
    def num_vertices(self) -> int: ...
    @property
    def num_faces(self) -> int: ...
    def copy(self) -> Mesh: ...

class NoisyMesh:
    mesh: Mesh
    V: npt.NDArray[np.float64]
    F: npt.NDArray[np.int32]
    N: npt.NDArray[np.float64]
    covariances: npt.NDArray[np.float64]  # (n, 3, 3), model units²
    pixel: npt.NDArray[np.float32]  # (n, 2) or (0, 2)
    @overload
    def __init__(self, mesh: Mesh, covariances: Optional[ArrayLike] = ...) -> None: ...
    @overload
    def __init__(self, V: ArrayLike, F: ArrayLike, covariances: Optional[ArrayLike] = ...) -> None: ...
    @property
    def has_covariance(self) -> bool: ...
    @property
    def num_vertices(self) -> int: ...
    @property
    def num_faces(self) -> int: ...
    def copy(self) -> NoisyMesh: ...

class CornerNormals:
    @property
    def normals(self) -> npt.NDArray[np.float64]: ...
    @property
    def normal_index(self) -> npt.NDArray[np.int32]: ...

def read_mesh(path: StrPath) -> Union[Mesh, NoisyMesh]: ...
def read_noisy_mesh(path: StrPath) -> NoisyMesh: ...
def write_mesh(path: StrPath, mesh: Union[Mesh, NoisyMesh, DecimatedMesh], ply_encoding: str = "binary") -> None: ...

# Smoothing
SMOOTH_OPTIONS: dict[str, Any]

class AdaptiveEpsilonSummary:
    per_face: bool
    gate_median_epsilon_squared: float
    median_epsilon_squared: float
    p10_epsilon_squared: float
    p90_epsilon_squared: float
    faces_at_minimum: int
    prepass_iterations: int
    prepass_evaluations: int
    prepass_time_s: float
    time_s: float

class NoiseEstimateDetails:
    one_ring: float
    growth: float
    tail: float
    raised_to_floor: bool

class GenericNoiseSummary:
    mean_edge_length: float
    noise_edge_multiple: float
    sigma: float
    estimated: bool
    estimate: NoiseEstimateDetails
    across_ratio: float

class NoiseModelChoice:
    from_file: bool
    replaced_file: bool
    generic: GenericNoiseSummary
    def brief_report(self) -> str: ...

class SmoothSummary:
    iterations: int
    evaluations: int
    energy: list[float]
    data_energy: float
    prior_energy: float
    prior_weight: float
    pixel_stride: float
    notices: list[str]
    initial_gradient_norm: float
    final_gradient_norm: float
    remaining_decrease: float
    termination: str
    time_s: float
    setup_time_s: float
    restarts: int
    flipped_faces: int
    input_flipped_faces: int
    inactive_faces: int
    num_threads: int
    potential_name: str
    memory_bytes: int
    levels: int
    continuation_stages: int
    coarse_work: float
    adaptive_epsilon_used: bool
    adaptive: AdaptiveEpsilonSummary
    noise_model: NoiseModelChoice
    def brief_report(self) -> str: ...

class LearnedPrior:
    num_knots: int
    epsilon_squared: float
    theta: npt.NDArray[np.float64]
    prior_weight: float
    noise_kind: str
    noise_k: float
    noise_k_max: float
    training_set: str
    training_pairs: int
    method: str
    regularizer_weight: float
    training_mse_le2: float
    date: str
    def __init__(self) -> None: ...

def smooth(
    mesh: Union[Mesh, NoisyMesh],
    noise: Optional[float] = ...,
    sigma: Optional[float] = ...,
    prior: Union[str, LearnedPrior] = "sqrt",
    *,
    across_ratio: float = ...,
    ignore_covariance: bool = ...,
    initial_positions: Optional[ArrayLike] = ...,
    progress: Optional[Progress] = ...,
    **options: Any,  # the SmoothOptions fields: see SMOOTH_OPTIONS
) -> Tuple[Mesh, SmoothSummary]: ...
def estimate_noise_level(mesh: Union[Mesh, NoisyMesh]) -> float: ...
def evaluate(
    ground_truth: Union[Mesh, NoisyMesh], result: Union[Mesh, NoisyMesh], surface_only: bool = ...
) -> dict[str, Union[float, int]]: ...
def make_generic_noisy_mesh(
    mesh: Union[Mesh, NoisyMesh], noise: Optional[float] = ..., sigma: Optional[float] = ..., across_ratio: float = ...
) -> Tuple[NoisyMesh, GenericNoiseSummary]: ...
def read_learned_prior(path: StrPath) -> LearnedPrior: ...
def write_learned_prior(path: StrPath, prior: LearnedPrior) -> None: ...
LEARN_PRIOR_OPTIONS: dict[str, Any]
def learn_prior(
    pairs: Sequence[Tuple[NoisyMesh, Mesh]], initial_theta: Optional[ArrayLike] = ..., *,
    progress: Optional[Progress] = ..., **options: Any
) -> Tuple[LearnedPrior, dict[str, Any]]: ...

# Decimation
DECIMATE_OPTIONS: dict[str, Any]

class DecimatedMesh:
    mesh: Mesh
    corner_normals: CornerNormals
    face_patch: list[int]
    vertex_source: list[int]
    dense_face_patch: list[int]
    polygons: list[list[int]]
    num_patches: int

class DecimateSummary:
    lambda_: float
    target_faces: int
    refitted: bool
    poses: int
    input_faces: int
    num_patches: int
    output_faces: int
    output_vertices: int
    energy: float
    data_energy: float
    fuses: int
    splits: int
    swaps: int
    rejected_disconnecting: int
    rounds: int
    converged: bool
    bisection_steps: int
    budget_faces: int
    lambda_too_many: float
    lambda_fits: float
    faces_too_many: int
    faces_fits: int
    max_chain_error_rel: float
    kept_corner_vertices: int
    blocked_vertices: int
    fell_back_to_dense: bool
    seconds_partition: float
    seconds_geometry: float
    seconds_refit_and_shading: float
    seconds_search_partition: float
    seconds_search_geometry: float
    refit_moved: int
    refit_blocked: int
    refit_flips: int
    refit_quadric_before: float
    refit_quadric_after: float
    refit_rms_before: float
    refit_rms_after: float
    seconds_total: float
    notices: list[str]
    def brief_report(self) -> str: ...

def decimate(mesh: Union[Mesh, NoisyMesh], *, progress: Optional[Progress] = ..., **options: Any) -> Tuple[DecimatedMesh, DecimateSummary]: ...
def decimate_animated(
    poses: Sequence[Union[Mesh, NoisyMesh]], *, progress: Optional[Progress] = ..., **options: Any
) -> Tuple[list[DecimatedMesh], DecimateSummary]: ...

# Calibration, stereo, reconstruction
class CameraIntrinsics:
    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    width: int
    height: int
    def __init__(self) -> None: ...

class StereoRig:
    width: int
    height: int
    K_left: npt.NDArray[np.float64]
    K_right: npt.NDArray[np.float64]
    distortion_left: npt.NDArray[np.float64]
    distortion_right: npt.NDArray[np.float64]
    R_right_from_left: npt.NDArray[np.float64]
    t_right_from_left_m: npt.NDArray[np.float64]
    is_rectified: bool
    R1: npt.NDArray[np.float64]
    R2: npt.NDArray[np.float64]
    P1: npt.NDArray[np.float64]
    P2: npt.NDArray[np.float64]
    Q: npt.NDArray[np.float64]
    doffs_px: float
    rms_left_px: float
    rms_right_px: float
    rms_stereo_px: float
    epipolar_error_px: float
    view_names: list[str]
    view_rms_stereo_px: list[float]
    def __init__(self) -> None: ...
    def rectified_left(self) -> CameraIntrinsics: ...
    def baseline_m(self) -> float: ...

def read_rig(path: StrPath) -> StereoRig: ...
def write_rig(path: StrPath, rig: StereoRig) -> None: ...

class DisparityNoiseModel:
    form: str
    sigma_px: float
    floor_px: float
    scale: float
    matcher: str
    samples: int
    outlier_fraction: float
    depth_slope_px_per_m: float
    image_noise_gray: float
    jump_scale: float
    width_min_px: int
    width_max_px: int
    window_px: int
    def __init__(self) -> None: ...
    def apply(self, sigma_pred_px: float, jump_px: float = 0.0) -> float: ...

def read_noise_model(path: StrPath) -> DisparityNoiseModel: ...
def write_noise_model(path: StrPath, model: DisparityNoiseModel) -> None: ...

BOARD_OPTIONS: dict[str, Any]
RIG_CALIBRATION_OPTIONS: dict[str, Any]
PLANE_NOISE_OPTIONS: dict[str, Any]
GROUND_TRUTH_NOISE_OPTIONS: dict[str, Any]

class StereoCalibrationSummary:
    pairs_given: int
    pairs_found: int
    pairs_used: int
    rms_left_px: float
    rms_right_px: float
    rms_stereo_px: float
    epipolar_error_mean_px: float
    epipolar_error_max_px: float
    right_camera_on_the_left: bool
    views: list[dict[str, Any]]
    def brief_report(self) -> str: ...

def calibrate_rig(
    left: Union[StrPath, Sequence[StrPath]], right: Union[StrPath, Sequence[StrPath]], *,
    board: dict[str, Any] = ..., progress: Optional[Progress] = ...,
    **options: Any  # the StereoCalibrationOptions fields: see RIG_CALIBRATION_OPTIONS
) -> Tuple[StereoRig, StereoCalibrationSummary]: ...

class NoiseCalibrationReport:
    outlier_fraction: float
    constant_sigma_px: float
    log_likelihood: float
    scenes: int
    samples: np.ndarray
    def brief_report(self) -> str: ...

def calibrate_noise(
    inputs: Union[StrPath, Sequence[StrPath]], *, target: str = ..., rig: Union[None, StrPath, StereoRig] = ...,
    form: Optional[str] = ..., roi: Optional[Tuple[int, int, int, int]] = ...,  # target="plane"
    progress: Optional[Progress] = ...,  # target="ground-truth"
    **options: Any  # PLANE_NOISE_OPTIONS or GROUND_TRUTH_NOISE_OPTIONS fields
) -> Tuple[DisparityNoiseModel, NoiseCalibrationReport]: ...

class NoiseModelCheck:
    samples: int
    observed_within: list[float]
    predicted_within: list[float]
    rms_within3: float
    predicted_rms_within3: float
    outlier_share: float
    def passes(self, max_share_error: float = 0.03, max_rms_error: float = 0.1) -> bool: ...
    def brief_report(self) -> str: ...

def check_noise_model(
    model: DisparityNoiseModel, scenes: Union[StrPath, Sequence[StrPath]], stride_px: int = 2, *,
    progress: Optional[Progress] = ...
) -> NoiseModelCheck: ...
def ground_truth_noise_samples(folder: StrPath, **options: Any) -> np.ndarray: ...

class MiddleburyScene:
    folder: str
    layout: str
    left: np.ndarray
    right: np.ndarray
    gt_disparity_px: Optional[np.ndarray]
    mask_nonocc: Optional[np.ndarray]
    num_disparities: int
    rig: Optional[StereoRig]

def read_middlebury_scene(folder: StrPath) -> MiddleburyScene: ...
def read_disparity(path: StrPath, scale: float = 1.0) -> np.ndarray: ...

DISPARITY_EVALUATION_OPTIONS: dict[str, Any]

class DisparityEvaluation:
    evaluated_pixels: int
    estimated_pixels: int
    coverage: float
    thresholds_px: list[float]
    bad_with_holes: list[float]
    bad_valid_only: list[float]
    rms_px: float
    mean_abs_px: float
    def brief_report(self) -> str: ...

def evaluate_disparity(
    estimate: ArrayLike, ground_truth: Union[MiddleburyScene, ArrayLike], mask: Optional[ArrayLike] = ...,
    *, bad_thresholds_px: Sequence[float] = ..., estimate_scale: float = ...
) -> DisparityEvaluation: ...

SYNTH_OPTIONS: dict[str, Any]

class SynthRecording:
    left: list[np.ndarray]
    right: list[np.ndarray]
    depth_m: np.ndarray
    disparity_px: np.ndarray
    rig: StereoRig
    intrinsics: CameraIntrinsics

def synth(*, out: Optional[StrPath] = ..., overwrite: bool = ..., **options: Any) -> SynthRecording: ...

class DepthFrame:
    depth_m: npt.NDArray[np.float32]
    sigma_depth_m: npt.NDArray[np.float32]
    disparity_px: npt.NDArray[np.float32]
    sigma_disparity_px: npt.NDArray[np.float32]
    edge_sigma_depth_m: Optional[npt.NDArray[np.float32]]
    frame_id: int
    timestamp_ns: int
    intrinsics: CameraIntrinsics
    baseline_m: float
    doffs_px: float
    sigma_pixel_px: float
    width: int
    height: int

Images = Union[ArrayLike, Sequence[ArrayLike]]
SGBM_OPTIONS: dict[str, Any]
SPACETIME_OPTIONS: dict[str, Any]
TRIANGULATE_OPTIONS: dict[str, Any]

def rectify(rig: StereoRig, left: ArrayLike, right: ArrayLike, **options: Any) -> Tuple[np.ndarray, np.ndarray]: ...
def match(left: Images, right: Images, matcher: str = "sgbm", **options: Any) -> dict[str, Any]: ...
def stereo(rig: StereoRig, left: Images, right: Images, matcher: str = "sgbm", depth: dict[str, Any] = ..., **options: Any) -> DepthFrame: ...
def depth_from_disparity(
    disparity: ArrayLike, sigma: Optional[ArrayLike], intrinsics: CameraIntrinsics, baseline_m: float,
    doffs_px: float = 0.0, **options: Any
) -> DepthFrame: ...
def triangulate(frame: DepthFrame, **options: Any) -> NoisyMesh: ...

# Recordings and the pipeline
class StereoFrame:
    left: np.ndarray
    right: np.ndarray
    index: int
    timestamp_left_ns: int
    timestamp_right_ns: int
    pattern_id: int

class Recording:
    folder: str
    rig: Optional[StereoRig]
    meta: dict[str, str]
    def __len__(self) -> int: ...
    def __getitem__(self, i: int) -> StereoFrame: ...
    def __iter__(self) -> Iterator[StereoFrame]: ...

def open_recording(folder: StrPath) -> Recording: ...

class PipelineResult:
    index: int
    last_index: int
    timestamp_ns: int
    frames: int
    left_rectified: Optional[np.ndarray]
    depth: DepthFrame
    raw_mesh: NoisyMesh
    smoothed: Optional[Mesh]
    decimated: Optional[DecimatedMesh]
    error: str
    error_stage: str
    stereo_downsample: int
    smooth_iterations: int
    smooth_time_limited: bool
    smooth_distance: float
    smooth_warm_vertices: int

class StageTiming:
    name: str
    items: int
    errors: int
    total_ms: float
    mean_ms: float

class PipelineSummary:
    source: str
    frames_captured: int
    frames_skipped: int
    results: int
    failed: int
    dropped: int
    stopped: bool
    fatal_error: str
    errors: list[str]
    stages: list[StageTiming]
    notices: list[str]
    wall_s: float
    frames_per_s: float
    latency_mean_ms: float
    smooth_iterations_mean: float
    smooth_time_limited: int
    smooth_warm_started: int
    smooth_distance_mean: float

PIPELINE_OPTIONS: dict[str, Any]
def replay(
    recording: Union[StrPath, Recording], rig: Optional[StereoRig] = ..., *, live_path: bool = ...,
    progress: Optional[Progress] = ...,
    sgbm: dict[str, Any] = ..., spacetime: dict[str, Any] = ..., depth: dict[str, Any] = ...,
    triangulate: dict[str, Any] = ..., smoothing: dict[str, Any] = ...,  # SmoothOptions fields and "prior"
    decimation: dict[str, Any] = ..., playback: dict[str, Any] = ...,
    **options: Any  # the PipelineOptions fields: see PIPELINE_OPTIONS
) -> Tuple[list[PipelineResult], PipelineSummary]: ...

# Many scans, one model
SCAN_OPTIONS: dict[str, Any]
REGISTER_OPTIONS: dict[str, Any]
FUSE_OPTIONS: dict[str, Any]

class RegisterSummary:
    iterations: int
    levels: int
    time_s: float
    pairs: list[dict[str, Any]]
    def brief_report(self) -> str: ...

class FuseSummary:
    voxel_size: float
    grid: Tuple[int, int, int]
    observed_voxels: int
    measurements: int
    vertices: int
    faces: int
    boundary_edges: int
    time_s: float
    def brief_report(self) -> str: ...

class ModelSummary:
    registration: RegisterSummary
    pair_report: str
    smoothing: list[SmoothSummary]
    fusion: FuseSummary
    decimation: Optional[DecimateSummary]
    notices: list[str]

def fuse(
    scans: Sequence[Union[StrPath, Mesh, NoisyMesh]],
    poses: Union[None, StrPath, ArrayLike, Sequence[ArrayLike]] = ...,
    *, align: bool = ..., smooth: bool = ..., decimate: bool = ..., progress: Optional[Progress] = ...,
    scan: dict[str, Any] = ..., registration: dict[str, Any] = ..., smoothing: dict[str, Any] = ...,
    fusion: dict[str, Any] = ..., decimation: dict[str, Any] = ...,
) -> Tuple[Mesh, np.ndarray, ModelSummary]: ...

# Pictures
RENDER_OPTIONS: dict[str, Any]
def render(
    mesh: Union[Mesh, NoisyMesh, DecimatedMesh], *, frame_like: Optional[Union[Mesh, NoisyMesh]] = ...,
    view_direction: Sequence[float] = ..., up: Sequence[float] = ..., light_in_camera: Sequence[float] = ...,
    base_color: Sequence[float] = ..., background: Sequence[float] = ...,
    **options: Any  # the RenderOptions fields: see RENDER_OPTIONS
) -> np.ndarray: ...
def write_png(path: StrPath, image: np.ndarray) -> None: ...

# Open3D interop (needs open3d)
def to_open3d(mesh: Union[Mesh, NoisyMesh, DecimatedMesh]) -> Any: ...
def from_open3d(o3d_mesh: Any) -> Mesh: ...
