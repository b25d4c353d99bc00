"""An optional OpenAI-compatible chat endpoint that proposes a mission for free text.

Configured only from the environment, never shipped: ``CUFUND_LLM_BASE_URL`` (e.g. ``http://127.0.0.1:8080/v1``),
``CUFUND_LLM_MODEL`` and, if the endpoint needs one, ``CUFUND_LLM_API_KEY``. The request goes to
``{base}/chat/completions`` and nowhere else (no proxy from the environment, no redirects followed); the answer's
message must be one JSON object in the data form of :mod:`cufund.missions.mission_request_schema`, and
:func:`cufund.missions.parse_mission` validates it exactly as the grammar's output. Anything else (no endpoint, an
HTTP or network error, a reply that is too large, not JSON, nested too deeply, NaN or infinite numbers) raises
:class:`MissionRequestError` saying what.
"""

from __future__ import annotations

import json
import math
import os
import time
import urllib.error
import urllib.parse
import urllib.request
from dataclasses import dataclass
from typing import Any

from .fleet_context import FleetContext, MissionRequestError
from .mission_request_schema import __doc__ as _SCHEMA_DOC

__all__ = ["ENV_API_KEY", "ENV_BASE_URL", "ENV_MODEL", "LlmEndpoint", "propose_mission"]

ENV_BASE_URL = "CUFUND_LLM_BASE_URL"
ENV_MODEL = "CUFUND_LLM_MODEL"
ENV_API_KEY = "CUFUND_LLM_API_KEY"
MAX_REPLY_BYTES = 256 * 1024
"""The largest reply read [bytes]; a longer one is refused."""


class _NoRedirect(urllib.request.HTTPRedirectHandler):
    def redirect_request(self, *args: Any, **kwargs: Any) -> None:
        return None  # a redirect is answered as the HTTP error it is


@dataclass(frozen=True)
class LlmEndpoint:
    """An OpenAI-compatible chat endpoint: ``base_url`` (http or https, up to the ``/chat/completions`` path),
    ``model``, ``api_key`` (or empty) and ``timeout_s``, the longest wait for the reply [s] (each read, and the
    whole body)."""

    base_url: str
    model: str
    api_key: str = ""
    timeout_s: float = 30.0

    def __post_init__(self) -> None:
        u = urllib.parse.urlsplit(self.base_url)
        if u.scheme not in ("http", "https") or not u.netloc:
            raise MissionRequestError(f"{ENV_BASE_URL} must be an http:// or https:// URL, got {self.base_url!r}")
        if not self.model:
            raise MissionRequestError(f"{ENV_MODEL} must name the endpoint's model")

    @classmethod
    def from_env(cls) -> LlmEndpoint | None:
        """The endpoint the environment configures, or None when ``CUFUND_LLM_BASE_URL`` is unset or empty."""
        base = os.environ.get(ENV_BASE_URL, "").strip()
        if not base:
            return None
        return cls(base, os.environ.get(ENV_MODEL, "").strip(), os.environ.get(ENV_API_KEY, "").strip())

    @property
    def url(self) -> str:
        return self.base_url.rstrip("/") + "/chat/completions"


def _finite(s: str) -> float:
    v = float(s)
    if not math.isfinite(v):
        raise ValueError(f"a number out of range: {s[:40]}")
    return v


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number the mission accepts")


def _loads(text: str) -> Any:
    try:
        return json.loads(text, parse_float=_finite, parse_constant=_no_constant)
    except RecursionError:  # '[[[[...' within MAX_REPLY_BYTES: the decoder recurses once a level
        raise ValueError("nested too deeply") from None


def _unfenced(content: str) -> str:
    """The inside of a Markdown code fence (```json ... ```) around the whole message, else the message. String
    operations, not a regular expression: ``\\s*(.*?)\\s*`` over a long run of blanks backtracks in cubic time (a
    3-byte fence and 4000 spaces took 37 s)."""
    s = content.strip()
    if len(s) < 6 or not (s.startswith("```") and s.endswith("```")):
        return content
    inner = s[3:-3]
    return (inner[4:] if inner.startswith("json") else inner).strip()


def _prompt(ctx: FleetContext) -> str:
    return (
        "You turn a ground-station operator's request into one quadrotor fleet mission. Answer with ONE JSON object "
        "and nothing else, in this form:\n"
        + (_SCHEMA_DOC or "")
        + "\nThe fleet: vehicles "
        + ", ".join(ctx.names)
        + "; named fields: "
        + (", ".join(ctx.fields) or "none")
        + f"; altitudes {ctx.min_altitude:g} to {ctx.max_altitude:g} m; at most {ctx.max_waypoints} waypoints per "
        'vehicle. If the request cannot be a mission, answer {"mission": null, "reason": "..."}.'
    )


def propose_mission(text: str, fleet: Any = None, endpoint: LlmEndpoint | None = None) -> dict[str, Any]:
    """The endpoint's proposal for ``text`` (a plain mapping, not yet validated); ``endpoint`` defaults to the
    environment's (:meth:`LlmEndpoint.from_env`)."""
    ep = endpoint or LlmEndpoint.from_env()
    if ep is None:
        raise MissionRequestError(
            f"{text.strip()[:120]!r} is not one of the built-in phrases (zigzag, orbit, survey, go home, fly to, formation), and "
            f"free text needs a chat endpoint: none is configured (set {ENV_BASE_URL} and {ENV_MODEL}, and "
            f"{ENV_API_KEY} if it needs a key)"
        )
    ctx = FleetContext.of(fleet)
    body = json.dumps(
        {
            "model": ep.model,
            "temperature": 0,
            "messages": [{"role": "system", "content": _prompt(ctx)}, {"role": "user", "content": text}],
        }
    ).encode()
    headers = {"Content-Type": "application/json", "Accept": "application/json"}
    if ep.api_key:
        headers["Authorization"] = f"Bearer {ep.api_key}"
    opener = urllib.request.build_opener(urllib.request.ProxyHandler({}), _NoRedirect())
    request = urllib.request.Request(ep.url, data=body, headers=headers, method="POST")
    deadline = time.monotonic() + ep.timeout_s
    try:
        with opener.open(request, timeout=ep.timeout_s) as reply:
            chunks: list[bytes] = []
            size = 0
            while size <= MAX_REPLY_BYTES:  # timeout_s bounds each socket read; this, the whole reply
                chunk = reply.read1(64 * 1024)
                if not chunk:
                    break
                chunks.append(chunk)
                size += len(chunk)
                if time.monotonic() > deadline:
                    raise MissionRequestError(f"the chat endpoint took longer than {ep.timeout_s:g} s to answer")
            raw = b"".join(chunks)
    except urllib.error.HTTPError as e:
        e.close()  # it holds the reply's connection
        raise MissionRequestError(f"the chat endpoint answered HTTP {e.code} {e.reason}"[:300]) from None
    except (urllib.error.URLError, OSError) as e:
        reason = getattr(e, "reason", e)
        raise MissionRequestError(f"the chat endpoint at {ep.url} cannot be reached: {reason}") from None
    if len(raw) > MAX_REPLY_BYTES:
        raise MissionRequestError(f"the chat endpoint's reply is over {MAX_REPLY_BYTES} bytes: refused")
    try:
        reply_data = _loads(raw.decode("utf-8"))
        content = reply_data["choices"][0]["message"]["content"]
    except (ValueError, KeyError, IndexError, TypeError, UnicodeDecodeError) as e:
        raise MissionRequestError(f"the chat endpoint's reply is not an OpenAI chat completion: {e}"[:300]) from None
    if not isinstance(content, str):
        raise MissionRequestError("the chat endpoint's message is not text")
    content = _unfenced(content)
    try:
        proposal = _loads(content)
    except ValueError as e:
        raise MissionRequestError(f"the chat endpoint's proposal is not valid JSON: {e}"[:300]) from None
    if not isinstance(proposal, dict):
        raise MissionRequestError(f"the chat endpoint's proposal is not a JSON object: {type(proposal).__name__}")
    if proposal.get("mission") is None and "reason" in proposal:
        raise MissionRequestError(f"the chat endpoint found no mission: {str(proposal['reason'])[:200]}")
    return proposal
