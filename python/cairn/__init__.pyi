# Type stubs of the cairn module (the C++ extension _cairn and the helpers of __init__.py).
# Units: metres, radians, seconds. Arrays are numpy arrays; results are read-only views
# into the C++ result where its layout allows.
from typing import Any, Dict, Iterator, List, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

__version__: str

CLASS_NONE: int
CLASS_KEPT: int
CLASS_REJECTED: int

class Error(ValueError, RuntimeError):
    """A library error: bad input, a bad file or a bad setting (the library's message)."""

class Settings:
    """Detector, rules, column, stereo, map, tilt and frame-check settings (defaults)."""
    def __init__(self) -> None: ...
    @property
    def path(self) -> Optional[str]: ...
    @property
    def min_height_m(self) -> float:
        """HT, least height of an obstacle [m]."""
    @property
    def max_height_m(self) -> float:
        """Hmax [m]."""
    @property
    def min_slope_rad(self) -> float:
        """theta from the horizontal [rad]."""
    @property
    def min_range_m(self) -> float: ...
    @property
    def threads(self) -> int:
        """Detector worker threads, 0 = every core."""
    @threads.setter
    def threads(self, value: int) -> None: ...
    @property
    def cell_size_m(self) -> float: ...
    @property
    def window_size_m(self) -> float: ...

def load_settings(path: str) -> Settings:
    """Reads a settings YAML with the command line's strict loaders; raises Error."""

def parse_settings(text: str, source: str = "settings") -> Settings: ...

class Detection:
    """One frame's obstacles."""
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def labels(self) -> npt.NDArray[np.int32]:
        """(rows, cols) segment id per cell, 0 = none."""
    @property
    def foot(self) -> npt.NDArray[np.uint8]:
        """(rows, cols) 1 at a segment's foot."""
    @property
    def classes(self) -> npt.NDArray[np.uint8]:
        """(rows, cols) 0 none, 1 kept, 2 rejected."""
    @property
    def point_labels(self) -> Optional[npt.NDArray[np.uint32]]:
        """(N,) per input point as labels.label: class | segment id << 16; None for depth."""
    @property
    def cell_of_point(self) -> Optional[npt.NDArray[np.int32]]:
        """(N,) each input point's cell (row * cols + col), -1 for no return."""
    @property
    def xyz(self) -> npt.NDArray[np.float32]:
        """(rows, cols, 3) sensor-frame points [m], NaN where no return."""
    @property
    def valid(self) -> npt.NDArray[np.uint8]: ...
    @property
    def R_level_sensor(self) -> npt.NDArray[np.float64]:
        """(3, 3) sensor frame -> level frame (z up)."""
    @property
    def up(self) -> npt.NDArray[np.float64]: ...
    @property
    def segments_json(self) -> str:
        """The text of segments.json."""
    @property
    def segments(self) -> List[Dict[str, Any]]:
        """segments.json's per-segment measures (units in the key names)."""
    @property
    def kept(self) -> int: ...
    @property
    def rejected(self) -> int: ...
    @property
    def obstacle_points(self) -> int: ...
    @property
    def valid_count(self) -> int: ...
    @property
    def method(self) -> str: ...
    @property
    def detect_seconds(self) -> float:
        """C++ detection time [s]."""
    @property
    def cpp_seconds(self) -> float:
        """All the C++ work of the call [s] (the rest is the binding's overhead)."""

def detect_points(
    points: npt.ArrayLike,
    sensor: Optional[str] = None,
    settings: Optional[Settings] = None,
    *,
    up: Sequence[float] = (0.0, 0.0, 1.0),
    organised: str = "auto",
    columns: int = 0,
    method: str = "cone",
    rules: bool = True,
    feet: bool = True,
    source: str = "points",
) -> Detection:
    """One LiDAR scan ((N, 3) or (N, 4), metres, LiDAR frame), as `cairn detect --points`."""

def detect_depth(
    depth_m: npt.ArrayLike,
    *,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    up: Sequence[float] = (0.0, -1.0, 0.0),
    settings: Optional[Settings] = None,
    method: str = "cone",
    rules: bool = True,
    feet: bool = True,
    source: str = "depth",
) -> Detection:
    """One (H, W) z-depth image [m], focal lengths and principal point [px]."""

def detect_frame(
    frame: Frame,
    settings: Optional[Settings] = None,
    *,
    method: str = "cone",
    rules: bool = True,
    feet: bool = True,
) -> Detection: ...

class CostGrid:
    """The 2.5-D grid as the map files hold it (row 0 = highest world y)."""
    @property
    def cost(self) -> npt.NDArray[np.uint8]:
        """(H, W) nav2 costs: 0 free .. 254 lethal, 255 unknown."""
    @property
    def occupancy(self) -> npt.NDArray[np.int8]:
        """(H, W) -1 unknown, 0..100 (OccupancyGrid)."""
    @property
    def elevation(self) -> npt.NDArray[np.float32]:
        """(H, W) ground elevation, world z [m], NaN unknown."""
    @property
    def origin(self) -> Tuple[float, float]:
        """World xy of the lower-left cell's outer corner [m]."""
    @property
    def resolution(self) -> float:
        """Cell side [m]."""
    @property
    def extent(self) -> Tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) [m] for matplotlib's imshow."""

class Mapper:
    """The library's map::Mapper: one call per frame."""
    def __init__(
        self,
        settings: Optional[Settings] = None,
        *,
        window_m: Optional[float] = None,
        refine_tilt: Optional[bool] = None,
        tilt: Optional[str] = None,
    ) -> None:
        """tilt: "prior" | "refine_to_map" | "gravity" (the gravity estimator's answer per
        frame is in the record's "gravity" dict)."""
    def add_points(
        self,
        points: npt.ArrayLike,
        T_world_sensor: npt.ArrayLike,
        *,
        stamp: float,
        sensor: Optional[str] = None,
        organised: str = "auto",
        columns: int = 0,
        source: str = "points",
    ) -> Dict[str, Any]:
        """One scan with its (4, 4) odometry pose and stamp [s]; returns the frame's record."""
    def add_depth(
        self,
        depth_m: npt.ArrayLike,
        T_world_sensor: npt.ArrayLike,
        *,
        stamp: float,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
    ) -> Dict[str, Any]: ...
    def add_frame(self, frame: Frame) -> Dict[str, Any]:
        """A frame of a reader, exactly as `cairn map` fuses it."""
    def cost_grid(self) -> CostGrid: ...
    def obstacles(self) -> List[Dict[str, Any]]: ...
    def save(self, dir: str) -> None:
        """Writes the map files of `cairn map` into dir."""
    @property
    def frames_processed(self) -> int: ...
    @property
    def frames_fused(self) -> int: ...

class Intrinsics:
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def fx(self) -> float: ...
    @property
    def fy(self) -> float: ...
    @property
    def cx(self) -> float: ...
    @property
    def cy(self) -> float: ...
    @property
    def depth_scale_m(self) -> float: ...
    @property
    def up(self) -> List[float]: ...

def load_intrinsics(path: str) -> Intrinsics: ...
def read_depth(path: str, intrinsics: Intrinsics) -> npt.NDArray[np.float32]:
    """(H, W) z-depth [m], 0 = no return."""
def read_points(path: str) -> npt.NDArray[np.float32]:
    """(N, 4) x, y, z [m], intensity."""
def read_labels(path: str) -> npt.NDArray[np.uint32]: ...
def write_labels(path: str, labels: npt.ArrayLike) -> None: ...
def read_segments_png(path: str) -> npt.NDArray[np.int32]: ...
def read_classes_png(path: str) -> npt.NDArray[np.uint8]: ...

class KittiScan:
    @property
    def index(self) -> int: ...
    @property
    def stamp_s(self) -> float: ...
    @property
    def path(self) -> str: ...
    @property
    def T_map_velodyne(self) -> Optional[npt.NDArray[np.float64]]: ...

def open_kitti(folder: str, range: str = "") -> List[KittiScan]: ...

class Frame:
    @property
    def index(self) -> int: ...
    @property
    def stamp_s(self) -> float: ...
    @property
    def name(self) -> str: ...
    @property
    def T_world_sensor(self) -> npt.NDArray[np.float64]: ...
    @property
    def T_world_body(self) -> npt.NDArray[np.float64]: ...
    @property
    def used(self) -> bool: ...
    @property
    def skip(self) -> str: ...
    @property
    def skip_detail(self) -> str: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def xyz(self) -> npt.NDArray[np.float32]: ...

class FrameSource(Iterator[Frame]):
    def __iter__(self) -> FrameSource: ...
    def __next__(self) -> Frame: ...
    def __len__(self) -> int: ...

def kitti_frames(
    folder: str, range: str = "", lidar: str = "HDL-64E", sequence: str = ""
) -> FrameSource: ...
def rawlog_frames(
    path: str, label: str = "", settings: Optional[Settings] = None
) -> FrameSource: ...
def depth_frames(folder: str, poses: str, intrinsics: str = "") -> FrameSource: ...
def label_class(point_labels: npt.NDArray[np.uint32]) -> npt.NDArray[np.uint32]: ...
def label_segment(point_labels: npt.NDArray[np.uint32]) -> npt.NDArray[np.uint32]: ...

# Evaluation against real labels (`cairn eval --labels`).
OUTCOME_NO_RETURN: int
OUTCOME_IGNORED: int
OUTCOME_TP: int
OUTCOME_FP: int
OUTCOME_FN: int
OUTCOME_TN: int

class ClassMap:
    """Which dataset classes are obstacles, ground or ignored (config/classes/*.yaml)."""
    @property
    def source(self) -> str: ...
    @property
    def dataset(self) -> str: ...
    @property
    def classes(self) -> List[Dict[str, Any]]:
        """One dict per class: id, name, role ("obstacle" | "ground" | "ignored"), color."""

def load_class_map(path: str) -> ClassMap: ...

class LabelScore:
    """Per-point obstacle score against true labels, as results.csv of `cairn eval`."""
    @property
    def tp(self) -> int: ...
    @property
    def fp(self) -> int: ...
    @property
    def fn(self) -> int: ...
    @property
    def tn(self) -> int: ...
    @property
    def ignored(self) -> int: ...
    @property
    def no_return(self) -> int: ...
    @property
    def precision(self) -> float: ...
    @property
    def recall(self) -> float: ...
    @property
    def f1(self) -> float: ...
    @property
    def iou(self) -> float: ...
    @property
    def outcome(self) -> npt.NDArray[np.uint8]:
        """(N,) per point: one of the OUTCOME_* values."""
    @property
    def per_class(self) -> List[Dict[str, Any]]:
        """One dict per class of the map: id, name, role, returns, detected, rejected."""

def score_labels(
    class_map: ClassMap,
    truth: npt.ArrayLike,
    point_labels: npt.ArrayLike,
    *,
    has_return: Optional[npt.ArrayLike] = None,
    truth_source: str = "truth",
) -> LabelScore:
    """Scores cairn's per-point labels (Detection.point_labels) against .label entries;
    has_return: non-zero where the point is a return (Detection.cell_of_point >= 0)."""
