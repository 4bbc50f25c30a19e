"""``quadnodes serve``: a saved graph file made live in the browser.

A local web application (Starlette on uvicorn): the graph as nodes and wires,
each node's settings as form fields, its status and error on the node, and 3-D
views of any mesh output. Every edit is validated like the file loader does,
written back to the file (comments kept), and re-runs only what it affects; an
edit of the file in a text editor updates the page. See ``docs/graphs.md``.

Examples
--------
>>> from quadnodes.server import Session, create_app
>>> callable(create_app)
True
"""

from __future__ import annotations

import os
import secrets
import sys
import threading
from pathlib import Path
from typing import TextIO

from .app import create_app
from .session import Session

__all__ = ["Session", "create_app", "serve"]


def serve(
    path: str | os.PathLike[str],
    *,
    host: str = "127.0.0.1",
    port: int = 8765,
    out: str | os.PathLike[str] | None = None,
    cache: str | os.PathLike[str] | None = None,
    browser: bool = True,
    stream: TextIO = sys.stdout,
) -> int:
    """Serve ``path`` in the foreground until Ctrl-C; returns the exit status.

    Parameters
    ----------
    path : path-like
        The graph file (.toml or .json).
    host, port
        Where to listen (127.0.0.1 by default: only this machine).
    out : path-like, optional
        Output folder (default ``out/<graph name>/``, as ``quadnodes run``).
    cache : path-like, optional
        Disk cache folder (default ``<out>/.cache``, shared with ``quadnodes run``).
    browser : bool
        Open the page in the default browser.

    Raises
    ------
    GraphError
        If the graph file is invalid at the start.
    """
    import uvicorn

    from ..graph import Cache
    from ..linalg import compiled

    compiled.warm_up()  # a live editor re-runs: load the compiled solver kernels once, in the background

    session = Session(path, out=out, cache=None if cache is None else Cache(cache, max_memory_entries=512))
    token = secrets.token_urlsafe(24)
    app = create_app(session, token=token)
    shown = f"[{host}]" if ":" in host else host
    url = f"http://{shown}:{port}/?token={token}"
    def ready() -> None:  # the socket listens: print the URL (one line), open the browser
        print(url, file=stream, flush=True)
        if host not in ("127.0.0.1", "localhost", "::1"):
            print(f"warning: listening on {host}: anyone who can reach this address and has the token can edit "
                  f"{Path(path).name}", file=stream, flush=True)
        if browser:
            import webbrowser

            threading.Thread(target=webbrowser.open, args=(url,), daemon=True).start()

    class _Server(uvicorn.Server):
        async def startup(self, sockets: list | None = None) -> None:
            await super().startup(sockets=sockets)
            if self.started:
                ready()

    config = uvicorn.Config(app, host=host, port=port, log_level="warning", lifespan="on", ws="websockets-sansio",
                            timeout_graceful_shutdown=3, ws_ping_interval=None)  # local: a long node may hold the GIL
    server = _Server(config)
    print(f"serving {path} (outputs in {os.path.relpath(session.out)}/); Ctrl-C to stop", file=stream, flush=True)
    try:
        server.run()
    except KeyboardInterrupt:  # uvicorn shut down and passes Ctrl-C on: that is the normal way to stop
        pass
    finally:
        session.close()
    print("stopped", file=stream, flush=True)
    return 0 if server.started else 1
