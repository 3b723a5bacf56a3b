"""Provides the reader of CAS Modbus Scanner logs (Chipkin Automation Systems).

The scanner's log window, copied or saved, shows one line per frame and per notice,
each with the time of day to the second:

    [22:24:05] Write task has completed successfully
    [22:24:05] <= Response: 0A 06 07 D2 27 10 33 C0
    [22:24:05] => Poll: 0A 06 07 D2 27 10 33 C0

The newest line comes first. The reader puts the lines in time order (last line
first) when the times fall down the file, or, where they cannot tell (all in one
second), when the first frame is a response and the last a poll; a note says so once.

`=> Poll` is what the scanner sent (it is the master), `<= Response` what it received.
Print time, whole seconds (resolution 1 s), no date. Other lines are events.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Sequence

from sniffer.model import Direction, Labels
from sniffer.sources.logs.base import ANSI, DAY, LogRecord, ParsedLog, hex_tokens, parse_stamp

CAS = "cas"

LINE = re.compile(r"^\s*(?P<stamp>\[\d{1,2}:\d\d:\d\d\])\s*(?P<rest>.*?)\s*$")
FRAME = re.compile(
    r"^(?:(?P<sent>=>\s*Poll|Poll|=>)|(?P<received><=\s*Response|Response|<=))\s*:\s*(?P<hex>.*)$",
    re.I,
)


def parse_cas(lines: Sequence[str], where: str) -> ParsedLog:
    parsed = ParsedLog(labels=Labels.HINT, client="CAS_Modbus_Scanner")
    parsed.channel_label = "CAS Modbus Scanner (=> Poll: sent, <= Response: received)"
    for number, raw_line in enumerate(lines, start=1):
        match = LINE.match(ANSI.sub("", raw_line))
        if match is None:
            continue
        stamp = parse_stamp(match["stamp"])
        frame = FRAME.match(match["rest"])
        if frame is None:
            parsed.event(number, stamp, match["rest"])
            continue
        data = hex_tokens(frame["hex"])
        if data is None:
            parsed.warnings.append(
                f"{where} line {number}: cannot read {frame['hex'][:30]!r} as hex bytes; "
                "the line is skipped (a cut or edited line?)"
            )
            continue
        direction = Direction.MASTER if frame["sent"] else Direction.SLAVE
        parsed.records.append(LogRecord(data, number, stamp, direction))
    if _newest_first(parsed.records):
        parsed.records.reverse()
        parsed.notes.append(
            f"{where}: CAS Modbus Scanner writes the newest line first; its "
            f"{len(parsed.records)} line(s) are read from the last to the first, in time order"
        )
    return parsed


def _newest_first(records: Sequence[LogRecord]) -> bool:
    """Whether the times fall down the file more often than they rise (a fall of more
    than half a day is midnight passed the other way); with no step either way, whether
    the first frame is a response and the last one a poll."""
    times = [r.stamp.seconds for r in records if r.stamp is not None]
    falls = rises = 0
    for before, after in itertools.pairwise(times):
        step = after - before
        if step > DAY / 2:
            step -= DAY
        elif step < -DAY / 2:
            step += DAY
        falls += step < 0
        rises += step > 0
    if falls != rises:
        return falls > rises
    frames = [r for r in records if r.data]
    return (
        len(frames) >= 2
        and frames[0].direction == Direction.SLAVE
        and frames[-1].direction == Direction.MASTER
    )
