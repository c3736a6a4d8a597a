"""pytest --nbval-lax notebooks/: runs each notebook in a kernel whose working directory is
notebooks/. Make relative NRSFM_DATA / NRSFM_OUT (e.g. NRSFM_DATA=data, relative to where
pytest was started) and relative PYTHONPATH entries (e.g. PYTHONPATH=. from the repository
root) absolute first, so the kernels inherit paths that still point at the same folders.
(nrsfm.paths resolves NRSFM_DATA / NRSFM_OUT against $PWD on its own; this keeps them right
for any code that reads the variables directly.)"""

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from build_notebooks import strict_ipython_dir  # noqa: E402

# every kernel starts with warnings as errors: a warning a notebook does not catch (and
# explain) fails its cell, as warnings fail the rest of the test run
os.environ["IPYTHONDIR"] = strict_ipython_dir()

for _name in ("NRSFM_DATA", "NRSFM_OUT"):
    _value = os.environ.get(_name)
    if _value and not os.path.isabs(_value):
        os.environ[_name] = str(Path(_value).resolve())

if os.environ.get("PYTHONPATH"):
    os.environ["PYTHONPATH"] = os.pathsep.join(
        str(Path(p).resolve()) for p in os.environ["PYTHONPATH"].split(os.pathsep) if p
    )
