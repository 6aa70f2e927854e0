"""cairn from Python: numpy in, numpy out, the same answers as the command line.

Obstacle detection in range images of cross-country terrain (the cone detector of Talukder,
Manduchi, Rankin and Matthies, IEEE IV 2002, and the column-wise baseline) and multi-frame
mapping into an OctoMap and a 2.5-D nav2 cost grid. Every call runs the C++ library's own
code path, the one `cairn detect` and `cairn map` run, without the GIL.

Units: metres, radians, seconds (degrees only in settings files). Frames: LiDAR x forward,
y left, z up; camera optical x right, y down, z forward; world z up.

    import cairn, numpy as np
    settings = cairn.load_settings("config/sensors/os1-64.yaml")
    scan = np.fromfile("000104.bin", np.float32).reshape(-1, 4)
    det = cairn.detect_points(scan, sensor="OS1-64", settings=settings)
    det.point_labels, det.labels, det.classes, det.segments

Errors of the library (bad input, bad files, bad settings) raise cairn.Error, a subclass of
ValueError and RuntimeError, with the library's message.
"""

from ._cairn import (  # noqa: F401
    OUTCOME_FN,
    OUTCOME_FP,
    OUTCOME_IGNORED,
    OUTCOME_NO_RETURN,
    OUTCOME_TN,
    OUTCOME_TP,
    ClassMap,
    CostGrid,
    Detection,
    Error,
    Frame,
    FrameSource,
    Intrinsics,
    KittiScan,
    LabelScore,
    Mapper,
    Settings,
    __version__,
    depth_frames,
    detect_depth,
    detect_frame,
    detect_points,
    kitti_frames,
    load_class_map,
    load_intrinsics,
    load_settings,
    open_kitti,
    parse_settings,
    rawlog_frames,
    read_classes_png,
    read_depth,
    read_labels,
    read_points,
    read_segments_png,
    score_labels,
    write_labels,
)

#: What the low 16 bits of a point label mean (labels.label, Detection.point_labels).
CLASS_NONE, CLASS_KEPT, CLASS_REJECTED = 0, 1, 2


def label_class(point_labels):
    """The class part of point labels: 0 none, 1 kept, 2 rejected (numpy array in, out)."""
    return point_labels & 0xFFFF


def label_segment(point_labels):
    """The segment-id part of point labels (0 = none)."""
    return point_labels >> 16


__all__ = [name for name in dir() if not name.startswith("_")]
