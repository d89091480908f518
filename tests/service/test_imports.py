"""The API does not load the engine's compiled code to serve: ``import service.app`` loads no
numba (the schemas read the engine's plain data, the pictures' catalogue lists what a job has);
the engine is imported when the API draws with it."""

from __future__ import annotations

import subprocess
import sys


def test_importing_the_api_loads_no_numba() -> None:
    code = (
        "import sys\n"
        "import service.app\n"
        "app = service.app.create_app\n"
        "assert 'numba' not in sys.modules, 'numba loaded'\n"
        "assert 'nanonav.engine.simulation' not in sys.modules, 'the engine loaded'\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
