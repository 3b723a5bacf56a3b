"""Provides `bytes_read`: how many bytes this process has read from files (Linux), which
is how far a reader got through a capture whatever the format's overhead."""

from __future__ import annotations


def bytes_read() -> int | None:
    """Bytes this process has read from files so far (`rchar` of /proc/self/io: reads
    of every file, terminals too), else None (not Linux)."""
    try:
        with open("/proc/self/io", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("rchar:"):
                    return int(line.split()[1])
    except (OSError, ValueError):
        return None
    return None
