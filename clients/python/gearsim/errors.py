# SPDX-License-Identifier: MIT
"""Errors raised by the gearsim client."""


class GearsimError(Exception):
    """An error reply from gearsimd (or a client-side failure with the same shape).

    code    -- stable machine-readable string (docs/reference/protocol.md), e.g. "out_of_range";
               client-side failures use "timeout", "not_found", "bad_json" and
               "daemon_stopped" (the daemon is gone: the message says why)
    message -- human sentence
    field   -- JSON path of the offending field ("" or None when no field is at fault)
    reply   -- the full reply or event that carried the error, when there was one
    """

    def __init__(self, code, message, field=None, reply=None):
        super().__init__(code, message, field)
        self.code = code
        self.message = message
        self.field = field or None
        self.reply = reply

    def __str__(self):
        s = f"{self.code}: {self.message}"
        if self.field:
            s += f" (field {self.field})"
        return s


class GearsimTimeout(GearsimError):
    """No reply (or no done event) within the allowed time, retries included."""

    def __init__(self, message):
        super().__init__("timeout", message)
