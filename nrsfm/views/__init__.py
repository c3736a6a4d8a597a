"""Views of a reconstruction, apart from the method: what to draw (:mod:`.content`, numpy),
the Rerun recordings of a reconstruction (:mod:`.recording`) and of a video run
(:mod:`.video`) with their helpers and layouts (:mod:`.rerun_log`, :mod:`.blueprint`),
matplotlib figures (:mod:`.figures`), notebook outputs and viewer (:mod:`.notebook`). rerun
and matplotlib are imported only when a function needs them."""

from .blueprint import make_blueprint, make_perspective_blueprint, make_video_blueprint
from .content import RecordingContent, recording_content
from .notebook import output_path, show_recording, shown_path
from .recording import (
    ENTITY_PATHS,
    PERSPECTIVE_ENTITY_PATHS,
    build_recording,
    log_content,
    save_recording,
)
from .video import VIDEO_ENTITY_PATHS, save_video_recording
