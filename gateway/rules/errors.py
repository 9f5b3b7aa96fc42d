"""Refusals of the gateway's domain (a booking, a run, a recording): each carries the HTTP status
that says why, and the web layer turns every one into its JSON answer in one place
(``web.api.JsonHandler``), so domain code raises no HTTP error of tornado's."""

from __future__ import annotations


class Refusal(Exception):
    """``status``: the HTTP status that says why (400, 403, 404, 409, 429, 500); ``message``: the why."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status, self.message = status, message
