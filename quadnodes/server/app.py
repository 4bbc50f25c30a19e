"""The ASGI application of ``quadnodes serve``: the page, its assets and the JSON API.

Every route needs the per-start token, as ``?token=…`` or an
``Authorization: Bearer …`` header; the WebSocket also checks its ``Origin``
(it must be the page's own host). No route evaluates code: requests carry JSON
data that goes through the graph file loader's validation (see
:class:`~quadnodes.server.session.Session`).

Routes (documented in ``docs/graphs.md``)::

    GET    /                              the page
    GET    /static/{file}                 its assets (plotly.js from the installed plotly package)
    GET    /api/graph                     the graph as the file model, positions, node types, refused edits
    GET    /api/palette                   every registered node type
    GET    /api/run                       the latest run: per node ran / cached / failed, times, messages
    GET    /api/mesh/{id}/{port}          a mesh output (base64 float32/int32 arrays; ?encoding=list for lists)
    POST   /api/nodes/{id}/settings       {"setting": value, ...}; null resets to the default
    POST   /api/nodes                     {"op": ..., "id"?: ..., "inputs"?: {...}, "params"?: {...}, "pos"?: [x, y]}
    DELETE /api/nodes/{id}
    POST   /api/connect                   {"node": id, "port": input, "source": "other.output"}
    POST   /api/disconnect                {"node": id, "port": input}
    POST   /api/layout                    {"positions": {id: [x, y]}}
    WS     /api/events                    events: graph, run, node, refused
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import secrets
from collections.abc import AsyncIterator
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import FileResponse, HTMLResponse, JSONResponse, Response
from starlette.routing import Route, WebSocketRoute
from starlette.websockets import WebSocket, WebSocketDisconnect

from ..errors import GraphError
from .session import Session

__all__ = ["create_app", "STATIC"]

#: The page's assets, shipped inside the package.
STATIC = Path(str(resources.files("quadnodes.server") / "static"))
_ASSETS = {"app.js": "text/javascript", "style.css": "text/css"}


def _plotly_js() -> Path:
    import plotly

    return Path(plotly.__file__).parent / "package_data" / "plotly.min.js"


def create_app(session: Session, *, token: str | None = None, poll_interval: float = 0.3) -> Starlette:
    """The Starlette app serving ``session``.

    Parameters
    ----------
    session : Session
    token : str, optional
        The access token (default: a new random one, ``app.state.token``).
    poll_interval : float
        Seconds between checks of the graph file's stamp (edits in a text editor).

    Returns
    -------
    Starlette
        ``app.state.token`` holds the token, ``app.state.session`` the session.
    """
    token = token or secrets.token_urlsafe(24)

    def authorized(conn: Request | WebSocket) -> bool:
        given = conn.query_params.get("token")
        auth = conn.headers.get("authorization", "")
        if given is None and auth.lower().startswith("bearer "):
            given = auth[7:].strip()
        return given is not None and secrets.compare_digest(given.encode(), token.encode())

    def denied() -> Response:
        return JSONResponse({"error": "missing or wrong token: open the URL with ?token=... that quadnodes serve "
                                      "printed on the console"}, status_code=401)

    def guarded(handler: Any) -> Any:
        async def endpoint(request: Request) -> Response:
            if not authorized(request):
                return denied()
            try:
                return await handler(request)
            except GraphError as exc:
                return JSONResponse({"ok": False, "error": str(exc), "node": getattr(exc, "node_id", None)},
                                    status_code=404 if "no node" in str(exc) or "no output" in str(exc) else 409)

        return endpoint

    async def body(request: Request) -> Any:
        try:
            return json.loads(await request.body() or b"null")
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise GraphError(f"request body: not JSON ({exc})") from None

    def answer(res: dict[str, Any]) -> JSONResponse:
        return JSONResponse(res, status_code=200 if res.get("ok") else 422)

    async def page(request: Request) -> Response:
        html = (STATIC / "index.html").read_text(encoding="utf-8")
        return HTMLResponse(html.replace("{{FILE}}", session.path.name.replace("<", "&lt;")),
                            headers={"Cache-Control": "no-store"})

    async def static(request: Request) -> Response:
        name = request.path_params["name"]
        if name == "plotly.min.js":
            return FileResponse(_plotly_js(), media_type="text/javascript")
        if name not in _ASSETS:
            return JSONResponse({"error": f"no asset {name!r}"}, status_code=404)
        return FileResponse(STATIC / name, media_type=_ASSETS[name], headers={"Cache-Control": "no-store"})

    async def graph(request: Request) -> Response:
        return JSONResponse(await asyncio.to_thread(session.describe))

    async def palette(request: Request) -> Response:
        return JSONResponse(session.palette())

    async def run_info(request: Request) -> Response:
        return JSONResponse(session.run_info())

    async def mesh(request: Request) -> Response:
        p = request.path_params
        data = await asyncio.to_thread(session.mesh, p["id"], p["port"],
                                       encoding=request.query_params.get("encoding", "base64"))
        return JSONResponse(data)

    async def settings(request: Request) -> Response:
        data = await body(request)
        return answer(await asyncio.to_thread(session.set_settings, request.path_params["id"], data))

    async def add(request: Request) -> Response:
        data = await body(request)
        if not isinstance(data, dict) or not isinstance(data.get("op"), str):
            raise GraphError('add a node: expected {"op": "name@version", ...}')
        return answer(await asyncio.to_thread(session.add_node, data["op"], node_id=data.get("id"),
                                              inputs=data.get("inputs"), params=data.get("params"),
                                              pos=data.get("pos")))

    async def delete(request: Request) -> Response:
        return answer(await asyncio.to_thread(session.delete_node, request.path_params["id"]))

    async def connect(request: Request) -> Response:
        data = await body(request)
        if not isinstance(data, dict) or not all(isinstance(data.get(k), str) for k in ("node", "port", "source")):
            raise GraphError('connect: expected {"node": id, "port": input, "source": "other.output"}')
        return answer(await asyncio.to_thread(session.connect, data["node"], data["port"], data["source"]))

    async def disconnect(request: Request) -> Response:
        data = await body(request)
        if not isinstance(data, dict) or not all(isinstance(data.get(k), str) for k in ("node", "port")):
            raise GraphError('disconnect: expected {"node": id, "port": input}')
        return answer(await asyncio.to_thread(session.disconnect, data["node"], data["port"]))

    async def layout(request: Request) -> Response:
        data = await body(request)
        positions = data.get("positions") if isinstance(data, dict) else None
        return answer(await asyncio.to_thread(session.move, positions))

    async def events(ws: WebSocket) -> None:
        origin = ws.headers.get("origin")
        if not authorized(ws) or (origin is not None and urlsplit(origin).netloc != ws.headers.get("host")):
            await ws.close(code=1008)
            return
        await ws.accept()
        loop = asyncio.get_running_loop()
        queue: asyncio.Queue[dict[str, Any]] = asyncio.Queue()
        unsubscribe = session.subscribe(lambda ev: loop.call_soon_threadsafe(queue.put_nowait, ev))
        async def pump() -> None:
            await ws.send_json({"type": "hello", "revision": session.revision})
            while True:
                await ws.send_json(await queue.get())

        sender = asyncio.create_task(pump())
        try:
            while (await ws.receive())["type"] != "websocket.disconnect":
                pass  # the page sends nothing; this notices when it goes (or the server shuts down)
        except (WebSocketDisconnect, RuntimeError):
            pass
        finally:
            unsubscribe()
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, WebSocketDisconnect, RuntimeError, OSError):
                await sender

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette) -> AsyncIterator[None]:
        session.start()

        async def poll() -> None:
            while True:
                await asyncio.sleep(poll_interval)
                await asyncio.to_thread(session.poll)

        task = asyncio.create_task(poll())
        try:
            yield
        finally:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
            await asyncio.to_thread(session.close)

    routes = [
        Route("/", guarded(page)),
        Route("/static/{name}", guarded(static)),
        Route("/api/graph", guarded(graph)),
        Route("/api/palette", guarded(palette)),
        Route("/api/run", guarded(run_info)),
        Route("/api/mesh/{id}/{port}", guarded(mesh)),
        Route("/api/nodes/{id}/settings", guarded(settings), methods=["POST"]),
        Route("/api/nodes", guarded(add), methods=["POST"]),
        Route("/api/nodes/{id}", guarded(delete), methods=["DELETE"]),
        Route("/api/connect", guarded(connect), methods=["POST"]),
        Route("/api/disconnect", guarded(disconnect), methods=["POST"]),
        Route("/api/layout", guarded(layout), methods=["POST"]),
        WebSocketRoute("/api/events", events),
    ]
    app = Starlette(routes=routes, lifespan=lifespan)
    app.state.token = token
    app.state.session = session
    return app
