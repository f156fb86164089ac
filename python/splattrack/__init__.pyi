"""Type stubs of splattrack (the native module and the frame readers)."""

import os
import pathlib
from typing import Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union, final

import numpy as np
import numpy.typing as npt

_PathLike = Union[str, os.PathLike[str]]
_Pose = Union[npt.NDArray[np.floating], Sequence[Sequence[float]]]

__all__ = [
    "Camera",
    "Error",
    "GpuError",
    "InputError",
    "Model",
    "ModelError",
    "MultiTracker",
    "Tracker",
    "TrackError",
    "TrackResult",
    "__version__",
    "device",
    "iter_frames",
    "list_images",
    "read_image",
    "track_frames",
]

__version__: str

class Error(Exception):
    """The base of splattrack's errors (files, the GPU, tracking)."""

class ModelError(Error):
    """A model file that cannot be read or used."""

class InputError(Error):
    """A camera, keyframe, pose, image or video file that cannot be read or used."""

class GpuError(Error):
    """No usable GPU adapter, or the device failed."""

class TrackError(Error):
    """The tracker cannot start or go on (a lost frame is not an error)."""

@final
class Camera:
    """A calibrated pinhole camera with OpenCV's distortion (k1, k2, p1, p2, k3)."""

    def __new__(
        cls,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
        width: int,
        height: int,
        distortion: Optional[Sequence[float]] = None,
    ) -> "Camera": ...
    @staticmethod
    def from_file(path: _PathLike) -> "Camera":
        """Reads camera.json or an OpenCV calibration YAML (InputError if it cannot)."""
    @property
    def fx(self) -> float: ...
    @property
    def fy(self) -> float: ...
    @property
    def cx(self) -> float: ...
    @property
    def cy(self) -> float: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def distortion(self) -> Tuple[float, float, float, float, float]: ...
    def matrix(self) -> npt.NDArray[np.float64]:
        """The 3x3 intrinsic matrix K."""

@final
class Model:
    """The object's point model."""

    @staticmethod
    def load(path: _PathLike, points: int = 0) -> "Model":
        """A point PLY, or a mesh (OBJ, STL, PLY with faces) sampled into
        ``points`` points (0: 100,000). ModelError if it cannot be read."""
    def __len__(self) -> int: ...
    @property
    def has_colors(self) -> bool: ...
    @property
    def positions(self) -> npt.NDArray[np.float32]:
        """Nx3 positions, model units."""

@final
class TrackResult:
    """What Tracker.track says about a frame."""

    @property
    def pose(self) -> npt.NDArray[np.float64]:
        """4x4 object-to-camera pose; the last good pose on a lost frame (NaN before the object was first found)."""
    @property
    def status(self) -> str:
        """"tracking" or "lost"."""
    @property
    def reason(self) -> Optional[str]:
        """None, or why the frame is lost, as the command line says it."""
    @property
    def inliers(self) -> int: ...
    @property
    def residual_px(self) -> float: ...
    @property
    def time_ms(self) -> float:
        """The tracker's time for the frame, milliseconds."""
    @property
    def keyframe(self) -> Optional[int]: ...
    @property
    def cues(self) -> str:
        """The cues that held the pose: texture, contour, texture+contour or none."""

@final
class Tracker:
    """Tracks a rigid object through the frames of one camera.

    ``keyframes``: a folder (images and poses.csv), a ``.stkf`` store, or a
    list of ``(image, pose)`` pairs. ``mode``: ``"kf+it"``, ``"it"`` or
    ``"kf"`` (default: kf+it with keyframes or model colours, else it).
    ``modalities``: ``"auto"``, ``"texture"``, ``"contour"`` or
    ``"texture,contour"``. ``device``: ``"auto"`` (a hardware GPU adapter
    when one opens, else the CPU), ``"gpu"`` or ``"cpu"`` (the host's cores, no GPU
    driver needed). The other keyword arguments are the command
    line's tuning flags under the same names (``kf_search=`` is
    ``--kf-search``).
    """

    def __new__(
        cls,
        model: Model,
        camera: Camera,
        keyframes: Union[None, _PathLike, Sequence[Tuple[npt.NDArray[np.uint8], _Pose]]] = None,
        *,
        mode: Optional[str] = None,
        modalities: str = "auto",
        device: str = "auto",
        splatter: str = "auto",
        feature_backend: str = "auto",
        resident: Union[None, bool, str] = None,
        harris_threshold: Optional[float] = None,
        max_corners: Optional[int] = None,
        min_score: Optional[float] = None,
        ncc_window: Optional[int] = None,
        it_search: Optional[float] = None,
        kf_search: Optional[float] = None,
        recover_search: Optional[float] = None,
        kf_iterations: Optional[int] = None,
        refine_iterations: Optional[int] = None,
        roi_margin: Optional[float] = None,
        min_inliers: Optional[int] = None,
        max_residual: Optional[float] = None,
        min_splat_px: Optional[float] = None,
        detail_px: Optional[float] = None,
        keep_radii: bool = False,
        min_valid: Optional[float] = None,
        max_it_only: Optional[int] = None,
        it_interior: Optional[float] = None,
        contour_rounds: Optional[int] = None,
        contour_converged: Optional[float] = None,
        contour_spacing: Optional[int] = None,
        contour_damping: Optional[float] = None,
        contour_full_render: bool = False,
        contour_reproject: Optional[float] = None,
        contour_sectors: Optional[int] = None,
        contour_no_seed: bool = False,
        full_frame: bool = False,
    ) -> "Tracker": ...
    def start(self, pose: _Pose) -> None:
        """Starts (or restarts) the track at the next frame's pose (4x4, object-to-camera)."""
    def track(self, frame: npt.NDArray[np.uint8]) -> TrackResult:
        """Tracks the next frame (HxWx3 uint8 RGB or HxW grey, the camera's size).
        Without start(), the first frames search for the object."""
    def render(
        self, pose: _Pose
    ) -> Tuple[npt.NDArray[np.uint8], npt.NDArray[np.float32], npt.NDArray[np.bool_]]:
        """The novel view at pose: (colour HxWx3 uint8, depth HxW float32 NaN where empty, mask HxW bool)."""
    @property
    def mode(self) -> str: ...
    @property
    def modalities(self) -> Optional[str]: ...
    @property
    def pose(self) -> Optional[npt.NDArray[np.float64]]: ...
    @property
    def camera(self) -> Camera: ...
    @property
    def keyframes(self) -> int: ...

@final
class MultiTracker:
    """Several objects through the frames of one camera: each object's
    model, keyframes and settings are those of the Tracker given for it
    (all with the same camera). ``objects``: a dict of name: Tracker, or a
    list of (name, Tracker) pairs; names unique, without commas, quotes
    or line breaks. With one object its poses are that Tracker's.
    """

    def __new__(
        cls,
        objects: Union[Mapping[str, Tracker], Sequence[Tuple[str, Tracker]]],
    ) -> "MultiTracker": ...
    def start(self, poses: Mapping[str, _Pose]) -> None:
        """Starts (or restarts) the track at the next frame's poses, by name;
        an object left out is searched for."""
    def track(self, frame: npt.NDArray[np.uint8]) -> Dict[str, TrackResult]:
        """Tracks the next frame: each object's result by name, in the objects' order."""
    @property
    def names(self) -> List[str]: ...
    @property
    def poses(self) -> Dict[str, Optional[npt.NDArray[np.float64]]]: ...
    def __len__(self) -> int: ...

def device(device: str = "auto") -> str:
    """The device ``device`` names: ``"gpu"`` (GpuError when there is
    none), ``"cpu"`` (the host's cores, no GPU driver) or ``"auto"`` (a hardware
    GPU adapter when one opens, else the CPU)."""

def read_image(path: _PathLike) -> npt.NDArray[np.uint8]:
    """A PNG or JPEG as HxWx3 uint8 RGB (InputError if it cannot be read)."""

def list_images(dir: _PathLike) -> List[pathlib.Path]:
    """The images of a folder in natural order of their names."""

def iter_frames(source: _PathLike) -> Iterator[npt.NDArray[np.uint8]]:
    """The frames of a frames folder, a sequence folder or a video file."""

def track_frames(tracker: Tracker, source: _PathLike) -> Iterator[Tuple[int, TrackResult]]:
    """Tracks every frame of source in order, yielding (index, result)."""
