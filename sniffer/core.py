"""Says which core runs: the compiled one (`sniffer._core`, a C extension that
`pip install` builds where a C compiler is found) or the pure-Python one.

The compiled core runs the loops that cost once a packet or a frame: the pcapng reader's
walk over link type 250 data records (`sniffer.sources.pcap`), the RTU framer's fast
paths with its timeline of reads (`sniffer.framing.serial`), and the passes over the indexed
rows: pairing (`sniffer.framing.pairing.Pairer.update`, `FrameStore.pair_rows`), the per-unit
statistics, their bounded tallies and their quantiles (`sniffer.analysis.stats`), the poll
cycle's requests and their waits (`sniffer.analysis.pollcycle.PollCycles.add`,
`_Waits.count`), the sidecar's checks of each block (`sniffer.session.index`), SunSpec's
first look at FC 3 and
FC 4 answers in any envelope (`sniffer.meaning.sunspec`), the joining of held batches of reads
(`sniffer.framing.pipeline`),
the pcapng export's packets from the templates it keeps
(`sniffer.outputs.export.PcapExporter`), and the text and JSONL listings' lines from the
parts they keep (`sniffer.outputs.listing.Lister`). Each is a copy of Python code that
stays, runs where the extension is missing, and takes over wherever the compiled loop
meets anything else, so both cores give the same rows, pairs, tables, packets and lines,
bit for bit (the export's
loop lets more rows share a packet template than the Python one, only rows whose packets
are the same but for the bytes it splices in: see `ex_packet_key` in sniffer/_core.c).
Where a loop needs a number of the product (a kind, a flag, a function code's family or
length, a limit of the readers) it is given it as a table (the RTU framer's length
rules, the poll cycle's same-poll rule) or says it back in `_core.constants()`, which
tests/core/test_core_constants.py holds to the Python that defines it.

`MODSCOPE_PURE_PYTHON=1` forces the pure-Python core. `modscope --version` says which
runs, and why not the compiled one.
"""

from __future__ import annotations

import importlib.util
import os
from types import ModuleType

# Every function of the compiled core the Python calls. An extension built from an older
# sniffer/_core.c (an editable install not rebuilt after a pull) lacks the newer ones: the
# pure-Python core then runs, saying why, rather than a call failing midway through a
# capture (tests/core/test_core_constants.py holds this to the module's functions).
FUNCTIONS = frozenset(
    {
        "bounds",
        "bulk_epbs",
        "bulk_pcap",
        "constants",
        "crc16",
        "export_moved",
        "export_rows",
        "export_table",
        "join_reads",
        "listing_floats",
        "listing_rows",
        "listing_table",
        "mask_rows",
        "pair_rows",
        "pair_update",
        "poll_block",
        "poll_table",
        "ranked",
        "rtu_scan",
        "shift_partners",
        "stats_scan",
        "sunspec_rows",
        "tally_gaps",
        "tally_latencies",
        "waits_count",
        "waits_densify",
    }
)


def stale(module: ModuleType) -> str:
    """Why `module` cannot be the compiled core: the functions it lacks ("" if none)."""
    missing = sorted(FUNCTIONS.difference(dir(module)))
    if not missing:
        return ""
    return (
        f"the compiled extension is older than the source (it lacks {', '.join(missing)}); "
        "rebuild it: pip install -e ."
    )


def _load() -> tuple[ModuleType | None, str]:
    if os.environ.get("MODSCOPE_PURE_PYTHON", "") == "1":
        return None, "MODSCOPE_PURE_PYTHON=1"
    if importlib.util.find_spec("sniffer._core") is None:
        return None, "the compiled extension is not built"
    try:
        from sniffer import _core  # type: ignore[attr-defined]
    except ImportError as exc:
        return None, f"the compiled extension does not load ({exc})"
    module: ModuleType = _core
    why = stale(module)
    return (None, why) if why else (module, "")


# The compiled module, or None for the pure-Python core. The readers and the framer look
# it up at each call, so tests can set it to None to run the pure-Python core.
FAST, REASON = _load()


def describe() -> str:
    """Which core runs, as `modscope --version` says it."""
    return "compiled core" if FAST is not None else f"pure-Python core: {REASON}"
