import os
import sys

from hypothesis import HealthCheck, settings

sys.path.insert(0, os.path.dirname(__file__))

settings.register_profile(
    "ci", max_examples=40, deadline=None, derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile("ci")


import pytest  # noqa: E402


@pytest.fixture
def read_only_folder(tmp_path, monkeypatch):
    """A folder ``tmp_path / "ro"`` in which no file can be created (``PermissionError``, EACCES).

    Root ignores permission bits, so the refusal is injected where the OS gives it: creating a file
    in the folder (``os.open`` with ``O_CREAT``, as ``mkstemp`` and ``open(..., "w")`` do).
    """
    ro = tmp_path / "ro"
    ro.mkdir()
    real_open = os.open

    def no_create(path, flags, *args, **kwargs):
        if os.path.dirname(os.path.abspath(os.fspath(path))) == str(ro) and flags & os.O_CREAT:
            raise PermissionError(13, "Permission denied", os.fspath(path))
        return real_open(path, flags, *args, **kwargs)

    monkeypatch.setattr(os, "open", no_create)
    return ro
