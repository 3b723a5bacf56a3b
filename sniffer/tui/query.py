"""Provides the frame list's filter language: a re-export of `sniffer.query`, where the
parser lives so that the command line's --filter reads queries without Textual."""

from __future__ import annotations

from sniffer.query import (
    EXAMPLES,
    KEYS,
    KIND_WORDS,
    STATUS_WORDS,
    Query,
    QueryError,
    TimePoint,
    TimeSpan,
    parse_query,
    parse_time_point,
    parse_time_span,
)

__all__ = [
    "EXAMPLES",
    "KEYS",
    "KIND_WORDS",
    "STATUS_WORDS",
    "Query",
    "QueryError",
    "TimePoint",
    "TimeSpan",
    "parse_query",
    "parse_time_point",
    "parse_time_span",
]
