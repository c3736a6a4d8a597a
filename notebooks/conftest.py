"""pytest --nbval-lax notebooks/: runs each notebook in a kernel whose working directory is
notebooks/. Make relative NRSFM_DATA / NRSFM_OUT (e.g. NRSFM_DATA=data, relative
to where pytest was started) absolute first, so the kernels inherit paths that still point
at the same folders."""

import os
from pathlib import Path

for _name in ("NRSFM_DATA", "NRSFM_OUT"):
    _value = os.environ.get(_name)
    if _value and not os.path.isabs(_value):
        os.environ[_name] = str(Path(_value).resolve())
