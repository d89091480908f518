"""Errors as RFC 9457 problem documents (``application/problem+json``), mapped in one place.

Every error a client can cause is a typed exception here or in the store; each maps to one status.
Validation errors carry the offending fields, as JSON pointers into the body or parameter names.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Sequence
from http import HTTPStatus
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from sqlalchemy.exc import OperationalError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.responses import Response

from nanonav.store import (
    IdempotencyKeyReused,
    JobAlreadyFinished,
    JobInStudy,
    JobNotFinished,
    JobNotFound,
    ResultsUnavailable,
    StudyNotFinished,
    StudyNotFound,
)
from nanonav.store.errors import PolicyInUse, PolicyLimitReached, QuotaExceeded
from service.methods import allowed_methods

PROBLEM_JSON = "application/problem+json"
PROBLEM_BASE = "urn:nanonav:problem:"
# How long a client over its quota is asked to wait before it submits again, seconds.
QUOTA_RETRY_AFTER_S = 30

logger = logging.getLogger(__name__)


class FieldError(BaseModel):
    """One offending input: where it is and what is wrong with it."""

    pointer: str | None = Field(
        None, description="JSON pointer into the request body, e.g. '#/robots/count'."
    )
    parameter: str | None = Field(None, description="Name of the offending query/path parameter.")
    loc: list[str | int] = Field(description="FastAPI-style location, e.g. ['body', 'robots'].")
    detail: str
    type: str


class Problem(BaseModel):
    """An RFC 9457 problem document."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "type": PROBLEM_BASE + "job-not-found",
                    "title": "Job not found",
                    "status": 404,
                    "detail": "there is no job 42",
                    "instance": "/jobs/42",
                }
            ]
        }
    )

    type: str = "about:blank"
    title: str
    status: int
    detail: str | None = None
    instance: str | None = None
    errors: list[FieldError] | None = None


class ProblemError(Exception):
    """An error the client caused, with the status and wording of its problem document."""

    status = 400
    slug = "bad-request"
    title = "Bad request"
    headers: dict[str, str] = {}  # noqa: RUF012  (read-only, per subclass)

    def __init__(self, detail: str, errors: Sequence[FieldError] = ()) -> None:
        super().__init__(detail)
        self.detail = detail
        self.errors = list(errors)


class BodyTooLarge(StarletteHTTPException):
    """Raised from inside the body stream, where only an HTTPException gets through FastAPI."""

    def __init__(self, limit: int) -> None:
        super().__init__(413, f"the request body is larger than {limit} bytes")


class UnsupportedMediaType(ProblemError):
    status = 415
    slug = "unsupported-media-type"
    title = "Unsupported media type"


class Unauthorized(ProblemError):
    status = 401
    slug = "unauthorized"
    title = "Unauthorized"
    headers = {"WWW-Authenticate": 'Bearer realm="nanonav", error="invalid_token"'}  # noqa: RUF012


class ForbiddenOrigin(ProblemError):
    status = 403
    slug = "forbidden-origin"
    title = "Forbidden origin"


class StudyFinished(ProblemError):
    status = 409
    slug = "study-finished"
    title = "Study already finished"


class NothingToRetry(ProblemError):
    status = 409
    slug = "nothing-to-retry"
    title = "Nothing to retry"


class NoQTable(ProblemError):
    status = 404
    slug = "no-qtable"
    title = "No Q-table"


class NoTreatment(ProblemError):
    status = 404
    slug = "no-treatment"
    title = "No treatment"


class NoMetric(ProblemError):
    status = 404
    slug = "no-metric"
    title = "No such metric in this study"


class NoCallback(ProblemError):
    status = 404
    slug = "no-callback"
    title = "No callback"


class EventsUnavailable(ProblemError):
    """The event poller is not running (the server is stopping, or it failed and logged why)."""

    status = 503
    slug = "events-unavailable"
    title = "Event streams unavailable"
    headers = {"Retry-After": "1"}  # noqa: RUF012  (read-only, per subclass)


class ChecksBusy(ProblemError):
    """Every process this API checks networks in is busy (``network_checks_at_once``)."""

    status = 503
    slug = "checks-busy"
    title = "Network checks busy"
    headers = {"Retry-After": "5"}  # noqa: RUF012  (read-only, per subclass)


class InvalidInput(ProblemError):
    status = 422
    slug = "invalid-input"
    title = "Invalid input"


class BudgetExceeded(InvalidInput):
    slug = "budget-exceeded"
    title = "Scenario over the work budget"


def problem_response(problem: Problem, headers: dict[str, str] | None = None) -> Response:
    return JSONResponse(
        problem.model_dump(exclude_none=True),
        status_code=problem.status,
        media_type=PROBLEM_JSON,
        headers=headers,
    )


def problems(*statuses: int) -> dict[int | str, dict[str, Any]]:
    """The ``responses=`` entry documenting a route's problem answers in OpenAPI."""
    return {
        status: {"model": Problem, "content": {PROBLEM_JSON: {}}, "description": "A problem"}
        for status in statuses
    }


def field_error(loc: Sequence[str | int], detail: str, kind: str) -> FieldError:
    where = list(loc)
    if where and where[0] == "body":
        tokens = (str(part).replace("~", "~0").replace("/", "~1") for part in where[1:])
        pointer = "#" + "".join(f"/{token}" for token in tokens)
        return FieldError(pointer=pointer, loc=where, detail=detail, type=kind)
    parameter = str(where[1]) if len(where) > 1 else None
    return FieldError(parameter=parameter, loc=where, detail=detail, type=kind)


def invalid_body(error: ValidationError) -> InvalidInput:
    """A validation error raised after the body was parsed, as the 422 a parsing error gets."""
    errors = [
        field_error(["body", *item["loc"]], item["msg"], item["type"])
        for item in error.errors(include_url=False)
    ]
    first = errors[0]
    return InvalidInput(f"{first.pointer}: {first.detail}", errors)


# The store's refusals a client reads as they are: status, problem slug and title for each.
STORE_ERRORS: dict[type[Exception], tuple[int, str, str]] = {
    JobNotFound: (404, "job-not-found", "Job not found"),
    StudyNotFound: (404, "study-not-found", "Study not found"),
    ResultsUnavailable: (409, "results-unavailable", "Results unavailable"),
    JobAlreadyFinished: (409, "job-finished", "Job already finished"),
    JobNotFinished: (409, "job-not-finished", "Job not finished"),
    JobInStudy: (409, "job-in-study", "Job belongs to a study"),
    StudyNotFinished: (409, "study-not-finished", "Study not finished"),
    PolicyInUse: (409, "policy-in-use", "Policy in use"),
    PolicyLimitReached: (409, "policy-limit", "Policy limit reached"),
}


def unreadable_body(cause: BaseException | None) -> str | None:
    """What made a JSON body unreadable where the framework says only that it could not parse
    it: bytes that are not UTF-8, nesting past the parser's depth, or a number of more digits
    than Python reads; None for any other cause."""
    if isinstance(cause, UnicodeDecodeError):
        return f"it is not UTF-8 ({cause.reason} at byte {cause.start})"
    if isinstance(cause, RecursionError):
        return "its arrays and objects nest too deeply (a scenario nests a few levels)"
    if isinstance(cause, ValueError) and "digits" in str(cause):
        limit = sys.get_int_max_str_digits()
        return f"it has a number of more than {limit} digits"
    return None


def _respond(
    request: Request,
    status: int,
    slug: str,
    title: str,
    detail: str,
    errors: Sequence[FieldError] = (),
) -> Response:
    problem = Problem(
        type=PROBLEM_BASE + slug,
        title=title,
        status=status,
        detail=detail,
        instance=request.url.path,
        errors=list(errors) or None,
    )
    return problem_response(problem)


async def _on_problem(request: Request, exc: Exception) -> Response:
    assert isinstance(exc, ProblemError)
    response = _respond(request, exc.status, exc.slug, exc.title, exc.detail, exc.errors)
    response.headers.update(exc.headers)
    return response


async def _on_store_error(request: Request, exc: Exception) -> Response:
    status, slug, title = next(STORE_ERRORS[t] for t in type(exc).__mro__ if t in STORE_ERRORS)
    return _respond(request, status, slug, title, str(exc))


async def _on_quota(request: Request, exc: Exception) -> Response:
    assert isinstance(exc, QuotaExceeded)
    response = _respond(request, 429, "quota-exceeded", "Quota exceeded", str(exc))
    response.headers["Retry-After"] = str(QUOTA_RETRY_AFTER_S)
    return response


async def _on_key_reused(request: Request, exc: Exception) -> Response:
    detail = str(exc)
    error = field_error(["header", "idempotency-key"], detail, "idempotency_key_reused")
    slug, title = "idempotency-key-reused", "Idempotency key reused"
    return _respond(request, 422, slug, title, detail, [error])


async def _on_validation(request: Request, exc: Exception) -> Response:
    assert isinstance(exc, RequestValidationError)
    errors = [
        field_error(
            [p for p in e.get("loc", ()) if isinstance(p, str | int)],
            str(e.get("msg", "")),
            str(e.get("type", "")),
        )
        for e in exc.errors()
    ]
    malformed = [e for e in exc.errors() if e.get("type") == "json_invalid"]
    if malformed:
        # the location of a JSON syntax error is a character offset, not a JSON pointer
        offset = next((p for p in malformed[0].get("loc", ()) if isinstance(p, int)), None)
        where = "" if offset is None else f" at character {offset}"
        reason = str(malformed[0].get("ctx", {}).get("error", "")) or "invalid JSON"
        return _respond(
            request,
            400,
            "malformed-json",
            "Malformed JSON",
            f"the request body is not valid JSON{where}: {reason}",
            [FieldError(pointer="#", loc=["body"], detail=f"{reason}{where}", type="json_invalid")],
        )
    first = errors[0] if errors else None
    detail = "the request is invalid"
    if first is not None:
        where = first.pointer or first.parameter or "/".join(map(str, first.loc))
        detail = f"{where}: {first.detail}"
    return _respond(request, 422, "invalid-input", "Invalid input", detail, errors)


async def _on_http(request: Request, exc: Exception) -> Response:
    assert isinstance(exc, StarletteHTTPException)
    if exc.status_code == 400 and (unread := unreadable_body(exc.__cause__)) is not None:
        error = FieldError(pointer="#", loc=["body"], detail=unread, type="json_invalid")
        detail = f"the request body is not valid JSON: {unread}"
        return _respond(request, 400, "malformed-json", "Malformed JSON", detail, [error])
    slug = {413: "body-too-large", 404: "not-found", 405: "method-not-allowed"}.get(
        exc.status_code, "http-error"
    )
    title = {413: "Content too large"}.get(exc.status_code, _reason(exc.status_code))
    response = _respond(request, exc.status_code, slug, title, str(exc.detail))
    if exc.headers:
        response.headers.update(exc.headers)
    if exc.status_code == 405:
        # the route that raised it knows only its own methods, not its path's
        response.headers["Allow"] = ", ".join(
            allowed_methods(request.app.router.routes, request.scope)
        )
    return response


async def _on_database_down(request: Request, exc: Exception) -> Response:
    logger.error("database error on %s %s: %s", request.method, request.url.path, exc)
    response = _respond(
        request,
        503,
        "database-unavailable",
        "Database unavailable",
        "the job store did not answer; try again shortly",
    )
    response.headers["Retry-After"] = "1"
    return response


async def _on_crash(request: Request, exc: Exception) -> Response:
    logger.exception("unhandled error on %s %s", request.method, request.url.path)
    return _respond(
        request,
        500,
        "internal-error",
        "Internal server error",
        "the server failed; this is a bug and has been logged",
    )


def install(app: FastAPI) -> None:
    """Map every error type to its problem document, once for the whole app."""
    app.add_exception_handler(ProblemError, _on_problem)
    for store_error in STORE_ERRORS:
        app.add_exception_handler(store_error, _on_store_error)
    app.add_exception_handler(QuotaExceeded, _on_quota)
    app.add_exception_handler(IdempotencyKeyReused, _on_key_reused)
    app.add_exception_handler(RequestValidationError, _on_validation)
    app.add_exception_handler(StarletteHTTPException, _on_http)
    app.add_exception_handler(OperationalError, _on_database_down)
    app.add_exception_handler(Exception, _on_crash)


def _reason(status: int) -> str:
    try:
        return HTTPStatus(status).phrase
    except ValueError:
        return "Error"
