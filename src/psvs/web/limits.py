"""Request hygiene for the web UI: a body size limit (ASGI middleware) and bounds on pipeline parameters,
so that a malformed or hostile request gets a 4xx answer and never stalls the server."""
from __future__ import annotations

import json

#: Largest pipeline: steps, and the largest value of each numeric step parameter.
MAX_STEPS = 8
PARAM_MAX = {"ksize": 31, "diameter": 31, "block": 255, "sigma": 20.0, "sigma_space": 20.0, "sigma_color": 1000.0,
             "level": 10000.0, "low": 10000.0, "high": 10000.0, "offset": 255.0}


def check_steps(steps) -> list[dict]:
    """Validate a pipeline's JSON steps [{"op": ..., param: value}] before building it (library checks follow)."""
    if not isinstance(steps, list) or not 1 <= len(steps) <= MAX_STEPS:
        raise ValueError(f"steps must be a list of 1 to {MAX_STEPS} steps")
    for i, spec in enumerate(steps):
        if not isinstance(spec, dict) or not isinstance(spec.get("op"), str):
            raise ValueError(f"steps[{i}] must be an object with a string 'op'")
        for key, value in spec.items():
            if key == "op":
                continue
            if key == "method":
                if not isinstance(value, str):
                    raise ValueError(f"steps[{i}].method must be a string")
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"steps[{i}].{key} must be a number, got {value!r}")
            limit = PARAM_MAX.get(key)
            if limit is None:
                raise ValueError(f"steps[{i}]: unknown parameter {key!r}")
            if not -limit <= value <= limit:
                raise ValueError(f"steps[{i}].{key} must be within +-{limit:g}, got {value!r}")
    return steps


class BodyLimit:
    """ASGI middleware: a request body above ``max_bytes`` (declared or streamed; ``larger``: {path: bytes} for
    the paths that take more, a video) gets 413 before the app sees it; smaller bodies are buffered and
    replayed to the app."""

    def __init__(self, app, max_bytes: int, larger: dict[str, int] | None = None):
        self.app, self.default, self.larger = app, max_bytes, dict(larger or {})

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        limit = self.larger.get(scope.get("path", ""), self.default)
        length = dict(scope.get("headers") or []).get(b"content-length")
        if length is not None:
            try:
                declared = int(length)
            except ValueError:
                return await reply_json(send, 400, "bad Content-Length")
            if declared > limit:
                return await reply_json(send, 413, f"request body over {limit} bytes")
        chunks, size = [], 0
        while True:
            message = await receive()
            if message["type"] == "http.disconnect":
                return
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > limit:
                return await reply_json(send, 413, f"request body over {limit} bytes")
            chunks.append(chunk)
            if not message.get("more_body", False):
                break
        body, sent = b"".join(chunks), False

        async def replay():
            nonlocal sent
            if not sent:
                sent = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()
        return await self.app(scope, replay, send)


async def reply_json(send, status: int, detail: str) -> None:
    """Answer ``{"detail": detail}`` with ``status`` and close the connection (the body may be unread)."""
    body = json.dumps({"detail": detail}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                            (b"connection", b"close")]})
    await send({"type": "http.response.body", "body": body})
