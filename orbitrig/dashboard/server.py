"""The dashboard's web server (aiohttp): one page, its assets, a small JSON API
and a websocket feed per browser.

- ``GET /``: the page (assets under ``/static/``, all inside the package);
- ``POST /api/login`` ``{"user", "password"}``: opens the person's MQTT
  connection; on success an HttpOnly, SameSite=Strict session cookie;
- ``POST /api/logout``, ``GET /api/session``;
- ``POST /api/cmd`` ``{"cmd", "rig", ...}``: one command as the signed-in user to the rig
  the page shows (``rig``: its topic prefix; refused if the session watches another by now,
  but a stop or abort, which goes to that rig when the dashboard knows it; a body with ``NaN`` or
  ``Infinity``, which JSON has not, is refused with 400, naming it);
- ``POST /api/ack`` ``{"alarm", "rig"}``: acknowledges a latched alarm as the signed-in user
  (orbitrig.dashboard.alarms: one book per rig, shared by the sessions);
- ``POST /api/rig`` ``{"rig"}``: the session watches another rig of the broker
  (orbitrig.dashboard.rigs);
- ``GET /api/feed``: websocket, server -> page JSON messages ``{"type", ...}`` (docs/protocols/dashboard-feed.md)
  (``hello``, ``link``, ``status``, ``ending``, ``progress``, ``live``, ``result``, ``gap``,
  ``trend``, ``trend_history``, ``alarms``, ``rigs``, ``rig``, ``outcomes``, ``outcome``, ``tick``, ``signed_out``);
  page -> server ``{"type": "active"}`` on user activity. A ``tick`` goes when nothing else went for
  ``defaults.TICK_S`` s (``--tick``): a page that hears nothing for longer knows its view is stale (a connection that died
  without closing), says so and connects again.
  A page's feed starts with the session's snapshot (``hello`` first): it replaces what the page
  showed (a page whose websocket reconnects draws the results again, not twice).

A session ends on sign-out or after ``idle_timeout`` s without a request or
user activity; a user's new sign-in beyond ``sessions_per_user`` ends that user's
oldest session. Refused sign-ins are throttled per user name and client address
(orbitrig.dashboard.throttle: 429 while a delay or a lockout lasts); every request
must be read within ``request_timeout`` s (orbitrig.dashboard.guard). Passwords
appear in no log, URL or page storage.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import time
from pathlib import Path
from typing import Any

from aiohttp import WSMsgType, web

from orbitrig.dashboard.alarms import AlarmShelf
from orbitrig.dashboard.defaults import MAX_SESSIONS
from orbitrig.dashboard.guard import RequestDeadline
from orbitrig.dashboard.feed import Feed, FeedType, text
from orbitrig.dashboard.session import DashboardSettings, Session, SignInRefused
from orbitrig.dashboard.throttle import SignInThrottle

log = logging.getLogger("orbitrig.dashboard")

STATIC = Path(__file__).resolve().parent / "static"
COOKIE = "orbitrig_session"
KEEPALIVE_S = 15.0  # an idle keep-alive connection is closed after this (s)
SECURITY_HEADERS = {
    "Cache-Control": "no-store",
    "Content-Security-Policy": "default-src 'self'; img-src 'self' data:; frame-ancestors 'none'",
    "X-Frame-Options": "DENY",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
}

SESSIONS = web.AppKey("sessions", dict)
SETTINGS = web.AppKey("settings", DashboardSettings)
THROTTLE = web.AppKey("throttle", SignInThrottle)
ALARMS = web.AppKey("alarms", AlarmShelf)


@web.middleware
async def _headers(request: web.Request, handler) -> web.StreamResponse:
    if request.method == "POST" and not _same_origin(request):
        return web.json_response({"error": "cross-origin request refused"}, status=403)
    response = await handler(request)
    response.headers.update(SECURITY_HEADERS)
    return response


def _same_origin(request: web.Request) -> bool:
    origin = request.headers.get("Origin")
    return origin is None or origin.split("://", 1)[-1] == request.host


def _session(request: web.Request) -> Session | None:
    token = request.cookies.get(COOKIE)
    session = request.app[SESSIONS].get(token) if token else None
    return None if session is None or session.closed else session


async def index(request: web.Request) -> web.StreamResponse:
    return web.FileResponse(STATIC / "index.html")


async def login(request: web.Request) -> web.Response:
    try:
        body = await request.json()
    except (ValueError, UnicodeDecodeError):
        return web.json_response({"error": "expected JSON {user, password}"}, status=400)
    user, password = body.get("user"), body.get("password")
    if not isinstance(user, str) or not isinstance(password, str) or not user or not password:
        return web.json_response({"error": "give a user name and a password"}, status=400)
    throttle, address = request.app[THROTTLE], request.remote or "?"
    if (why := throttle.refusal(user, address)) is not None:
        log.info("sign-in of %r from %s not tried: %s", user, address, why)
        return web.json_response({"error": why}, status=429)
    sessions: dict[str, Session] = request.app[SESSIONS]
    if len(sessions) - len(_oldest_beyond_cap(request.app, user)) >= MAX_SESSIONS:
        return web.json_response({"error": "too many sessions: sign out elsewhere first"}, status=503)
    session = Session(request.app[SETTINGS], user, password, request.app[ALARMS])
    del password, body
    try:
        await session.open()
    except SignInRefused as err:
        if err.credentials:
            throttle.failed(user, address)
        log.info("sign-in of %r from %s refused: %s", user, address, err)
        return web.json_response({"error": str(err)}, status=401)
    throttle.succeeded(user)
    old = _session(request)
    if old is not None:
        await _end(request.app, old, "signed in again")
    for oldest in _oldest_beyond_cap(request.app, user):
        await _end(request.app, oldest, "the same user signed in elsewhere (oldest session ended)")
    session.adopt(sessions.values())  # a sign-in in the middle of a run sees its trends and alarms so far
    sessions[session.token] = session
    log.info("%r signed in (%d sessions)", user, len(sessions))
    response = web.json_response(_who(session))
    response.set_cookie(COOKIE, session.token, httponly=True, samesite="Strict", path="/", secure=request.secure)
    return response


def _oldest_beyond_cap(app: web.Application, user: str) -> list[Session]:
    """The sessions of `user` to end so that a new one keeps them within sessions_per_user
    (the oldest first: the sessions dict keeps the sign-in order)."""
    own = [s for s in app[SESSIONS].values() if s.user == user]
    return own[: max(0, len(own) - app[SETTINGS].sessions_per_user + 1)]


async def logout(request: web.Request) -> web.Response:
    session = _session(request)
    if session is not None:
        await _end(request.app, session, "signed out")
    response = web.json_response({"ok": True})
    response.del_cookie(COOKIE, path="/")
    return response


async def whoami(request: web.Request) -> web.Response:
    session = _session(request)
    if session is None:
        return web.json_response({"error": "not signed in"}, status=401)
    session.touch()
    return web.json_response(_who(session))


def _who(session: Session) -> dict:
    """Who is signed in, the rig watched, the reply timeout (s: the page's deadlines follow it) and the tick (s:
    its stale and dead feed limits follow it)."""
    s = session.settings
    return {"user": session.user, "prefix": session.topics.prefix, "reply_timeout": s.reply_timeout, "tick": s.tick}


async def command(request: web.Request) -> web.Response:
    session = _session(request)
    if session is None:
        return web.json_response({"ok": False, "error": "not signed in"}, status=401)
    session.touch()
    try:
        body = await request.json(loads=_command_json)
    except (ValueError, UnicodeDecodeError) as err:
        return web.json_response({"ok": False, "error": f"expected a JSON command: {err}"}, status=400)
    if not isinstance(body, dict):
        return web.json_response({"ok": False, "error": "expected a JSON object"}, status=400)
    return web.json_response(await session.command(body))


def _command_json(text: str) -> Any:
    """A page's command read as JSON, which has no NaN nor infinity (the page's JSON.stringify writes null): a
    request with ``NaN``, ``Infinity`` or ``-Infinity`` is refused, naming it (ValueError)."""

    def not_json(constant: str) -> Any:
        raise ValueError(f"{constant} is not JSON (a value not known is null)")

    return json.loads(text, parse_constant=not_json)


async def feed(request: web.Request) -> web.StreamResponse:
    session = _session(request)
    if session is None or not _same_origin(request):
        return web.json_response({"error": "not signed in"}, status=401)
    ws = web.WebSocketResponse(heartbeat=20)
    await ws.prepare(request)
    queue = Feed()
    queue.start(session.snapshot())
    session.feeds.add(queue)
    sender = asyncio.create_task(_send_loop(ws, queue, session.settings.tick), name=f"feed-{session.user}")
    cutter = asyncio.create_task(_cut_when_behind(request, queue, session.user))
    try:
        async for msg in ws:
            if msg.type == WSMsgType.TEXT and '"active"' in msg.data:
                session.touch()
    finally:
        session.feeds.discard(queue)
        for task in (sender, cutter):
            task.cancel()
        await asyncio.gather(sender, cutter, return_exceptions=True)
    return ws


async def _cut_when_behind(request: web.Request, queue: Feed, user: str) -> None:
    """A page not reading while only messages it must not miss wait (orbitrig.dashboard.feed.Feed.behind):
    its connection is cut (a close frame would wait behind what it does not read); the page connects again
    and gets the session's snapshot (its results, warnings, run ends, alarms and status)."""
    await queue.behind.wait()
    log.warning(
        "session of %r: a page behind, %d messages (%d bytes) it must not miss waiting: its feed is closed",
        user,
        queue.counted,
        queue.bytes,
    )
    if request.transport is not None:
        request.transport.abort()


async def _field(request: web.Request, name: str) -> tuple[Session | None, str | web.Response, dict]:
    """The signed-in session, the text field ``name`` of the JSON body and the body, or the error response."""
    session = _session(request)
    if session is None:
        return None, web.json_response({"ok": False, "error": "not signed in"}, status=401), {}
    session.touch()
    try:
        body = await request.json()
    except (ValueError, UnicodeDecodeError):
        body = None
    if not isinstance(body, dict) or not isinstance(body.get(name), str):
        return None, web.json_response({"ok": False, "error": f"expected JSON {{{name}}}"}, status=400), {}
    return session, body[name], body


async def acknowledge(request: web.Request) -> web.Response:
    session, alarm, body = await _field(request, "alarm")
    if isinstance(alarm, web.Response):
        return alarm
    assert session is not None
    return web.json_response(await session.acknowledge(alarm, body.get("rig")))


async def select_rig(request: web.Request) -> web.Response:
    session, rig_id, _ = await _field(request, "rig")
    if isinstance(rig_id, web.Response):
        return rig_id
    assert session is not None
    return web.json_response(await session.select_rig(rig_id, list(request.app[SESSIONS].values())))


TICK = {"type": FeedType.TICK}


async def _send_loop(ws: web.WebSocketResponse, queue: Feed, tick: float) -> None:
    with contextlib.suppress(ConnectionError, RuntimeError):
        while not ws.closed:
            try:
                async with asyncio.timeout(tick):  # the feed's end (a cancel) not lost as a message comes
                    messages = await queue.take_written()
            except (TimeoutError, asyncio.TimeoutError):
                messages = [(TICK, text(TICK))]
            for message, json_text in messages:  # each written once for all the session's pages (feed.written)
                await ws.send_str(json_text)
                if message.get("type") == FeedType.SIGNED_OUT:
                    await ws.close()
                    return


async def _end(app: web.Application, session: Session, reason: str) -> None:
    app[SESSIONS].pop(session.token, None)
    await session.close(reason)
    log.info("session of %r ended: %s", session.user, reason)


async def _reaper(app: web.Application) -> None:
    """End sessions idle longer than idle_timeout and those whose broker refused them."""
    limit = app[SETTINGS].idle_timeout
    while True:
        now = time.monotonic()
        for session in list(app[SESSIONS].values()):
            if session.closed:
                await _end(app, session, "the broker refused the credentials")
            elif now - session.last_active > limit:
                await _end(app, session, f"idle for more than {limit:g} s")
        await asyncio.sleep(min(1.0, limit / 4))


async def _end_all(app: web.Application) -> None:
    """On shutdown, before aiohttp waits for the open connections: every session ends, so
    the pages' live feeds close instead of holding the stop for the shutdown timeout."""
    for session in list(app[SESSIONS].values()):
        await _end(app, session, "dashboard stopped")


async def _background(app: web.Application) -> Any:
    task = asyncio.create_task(_reaper(app), name="dashboard-reaper")
    yield
    task.cancel()
    await asyncio.gather(task, return_exceptions=True)
    for session in list(app[SESSIONS].values()):
        await _end(app, session, "dashboard stopped")


def make_app(settings: DashboardSettings) -> web.Application:
    app = web.Application(middlewares=[_headers], client_max_size=64 * 1024)
    app[SESSIONS] = {}
    app[SETTINGS] = settings
    app[THROTTLE] = SignInThrottle(settings.throttle)
    app[ALARMS] = AlarmShelf()  # the rigs' latched alarms: they outlive the sessions that saw them
    app.router.add_get("/", index)
    app.router.add_static("/static", STATIC, follow_symlinks=False)
    app.router.add_post("/api/login", login)
    app.router.add_post("/api/logout", logout)
    app.router.add_get("/api/session", whoami)
    app.router.add_post("/api/cmd", command)
    app.router.add_post("/api/ack", acknowledge)
    app.router.add_post("/api/rig", select_rig)
    app.router.add_get("/api/feed", feed)
    app.cleanup_ctx.append(_background)
    app.on_shutdown.append(_end_all)
    return app


async def serve(
    settings: DashboardSettings, host: str, port: int, shutdown: asyncio.Event, *, ssl_context: Any = None
) -> None:
    """Serve until ``shutdown`` is set (HTTPS with ``ssl_context``)."""
    runner = web.AppRunner(make_app(settings), access_log=None, keepalive_timeout=KEEPALIVE_S)
    await runner.setup()
    handler = runner.server
    assert handler is not None
    server = await asyncio.get_running_loop().create_server(
        lambda: RequestDeadline(handler(), settings.request_timeout), host, port, ssl=ssl_context
    )
    log.info(
        "dashboard on %s://%s:%d/ (broker %s:%d, topics %s/#)",
        "https" if ssl_context else "http",
        host,
        port,
        settings.host,
        settings.port,
        settings.topics.prefix,
    )
    try:
        await shutdown.wait()
    finally:
        server.close()
        await runner.cleanup()
