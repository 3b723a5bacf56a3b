"""Provides the one exception class for user errors: what the command line prints as one line.

A `UserError` is something the user can fix (a missing file, a port that refuses its
settings, a bad option); its message names the thing and the fix. Any other exception
that reaches the command line is a bug in modscope and is shown with its traceback.
`CaptureError` (a capture file that cannot be read at all) is one; `DictionaryError`
(in `dissectors`, which never imports `sniffer`) is one too. `USER_ERRORS` names them
all for the places that catch them.
"""

from __future__ import annotations

from dissectors.dictionary import DictionaryError


class UserError(Exception):
    """A problem with what the user asked for or gave; printed without a traceback."""


class CaptureError(UserError):
    """A capture file cannot be read at all. The message names the file and what to do."""


class UsageError(UserError):
    """An option or argument that cannot be used as given."""


USER_ERRORS: tuple[type[Exception], ...] = (UserError, CaptureError, DictionaryError)
"""Everything the command line prints as one line."""
