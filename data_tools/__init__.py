"""Data for nrsfm: benchmark loaders, synthetic sequences, noise, tracks from video."""

from nrsfm.sequence import Sequence

from .external import EXTERNAL, load_external
from .mocap import DAI_K, MOCAP_K, MOCAP_NAMES, load_all, load_mat, load_mocap, mocap_dir
from .noise import add_noise, drop_tracks
from .reprojection import parse_path, reproject, validation_set
from .synthetic import (
    MOTIONS,
    PerspectiveCamera,
    camera_rotations,
    default_sequence,
    make_rank_deficient,
    make_synthetic,
)
from .synthetic_video import SURFACES, SyntheticVideo, make_video, tracking_errors
from .video_truth import load_ground_truth, save_ground_truth, score_tracks, write_video
from .video import (
    Tracks,
    load_frames,
    read_frames,
    track_dense,
    track_sparse,
    tracks_from_frames,
    tracks_from_video,
)

__all__ = [
    "DAI_K",
    "EXTERNAL",
    "load_external",
    "parse_path",
    "reproject",
    "validation_set",
    "MOCAP_K",
    "MOCAP_NAMES",
    "MOTIONS",
    "Sequence",
    "add_noise",
    "camera_rotations",
    "default_sequence",
    "drop_tracks",
    "load_all",
    "load_mat",
    "load_mocap",
    "make_rank_deficient",
    "make_synthetic",
    "PerspectiveCamera",
    "mocap_dir",
    "read_frames",
    "tracks_from_frames",
    "tracks_from_video",
    "SURFACES",
    "SyntheticVideo",
    "Tracks",
    "load_frames",
    "make_video",
    "track_dense",
    "track_sparse",
    "tracking_errors",
    "load_ground_truth",
    "save_ground_truth",
    "score_tracks",
    "write_video",
]
