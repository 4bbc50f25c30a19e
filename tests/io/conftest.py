"""Helpers for the io tests: an independent STEP reader (gmsh) run in a subprocess."""

import importlib.util
import json
import subprocess
import sys

import pytest

# gmsh ships its own OpenCASCADE build; a separate process keeps it from
# meeting the OCP libraries already loaded by build123d in this one.
_GMSH_SCRIPT = r"""
import json, sys
import gmsh
gmsh.initialize(interruptible=False)
gmsh.option.setNumber("General.Terminal", 0)
counts = []
for path in sys.argv[1:]:
    gmsh.clear()
    gmsh.open(path)
    counts.append(len(gmsh.model.getEntities(2)))
gmsh.finalize()
print(json.dumps(counts))
"""


@pytest.fixture(scope="session")
def gmsh_face_counts():
    """``f(*paths) -> list[int]``: number of surfaces gmsh finds in each STEP file."""
    if importlib.util.find_spec("gmsh") is None:  # do not import it here
        pytest.skip("gmsh is not installed (pip install -e .[test])")

    def count(*paths):
        out = subprocess.run(
            [sys.executable, "-c", _GMSH_SCRIPT, *map(str, paths)],
            capture_output=True, text=True, timeout=120, check=True,
        )
        return json.loads(out.stdout.strip().splitlines()[-1])

    return count
