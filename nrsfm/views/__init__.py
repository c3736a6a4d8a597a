"""Views of a reconstruction, apart from the method.

* :mod:`~nrsfm.views.content`: what to draw (pure numpy: display-aligned shapes and
  cameras, per-frame errors, rotation samples, shape-stage history, report).
* :mod:`~nrsfm.views.recording`: Rerun recording of a reconstruction (entity paths there).
* :mod:`~nrsfm.views.video`: Rerun recording of a video run.
* :mod:`~nrsfm.views.rerun_log`: logging helpers both recordings share.
* :mod:`~nrsfm.views.blueprint`: the recordings' default layouts.
* :mod:`~nrsfm.views.notebook`: output locations and an embedded viewer in notebooks.
* :mod:`~nrsfm.views.figures`: matplotlib figures.

rerun and matplotlib are imported only when a function needs them.
"""

from .blueprint import make_blueprint, make_video_blueprint
from .content import RecordingContent, recording_content
from .notebook import output_path, show_recording, shown_path
from .recording import ENTITY_PATHS, build_recording, log_content, save_recording
from .video import VIDEO_ENTITY_PATHS, decimate, save_video_recording

__all__ = ["ENTITY_PATHS", "VIDEO_ENTITY_PATHS", "RecordingContent", "build_recording",
           "decimate", "log_content", "make_blueprint", "make_video_blueprint", "output_path",
           "recording_content", "save_recording", "save_video_recording", "show_recording",
           "shown_path"]
