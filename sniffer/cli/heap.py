"""Provides `settle`: start-up's objects kept out of the cyclic collector's way while a
capture is read, when modscope runs as the program."""

from __future__ import annotations

import gc

_program = False  # set by `sniffer.cli.main` when it reads the process's own arguments


def as_program() -> None:
    """This process is modscope, run as a command: `settle` may freeze the heap."""
    global _program
    _program = True


def settle() -> None:
    """Move what start-up built (modules, parsers, schemas, dictionaries), which lives as
    long as the process, out of the cyclic collector's reach (`gc.freeze`): its passes
    while a capture is read then walk only what the read made, not the start-up's
    objects again and again.

    Only when modscope runs as the program: a process that calls it as a library (the
    test suite) would keep whatever cyclic garbage is frozen with it for good."""
    if _program:
        gc.freeze()
