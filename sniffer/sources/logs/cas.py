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

import re
from collections.abc import Iterator

from sniffer.model import Direction, Labels
from sniffer.sources.logs.base import (
    ANSI,
    DAY,
    Lines,
    LogRecord,
    ParsedLog,
    hex_tokens,
    parse_stamp,
)

CAS = "cas"

LINE = re.compile(r"^\s*(?P<stamp>\[\d{1,2}:\d\d:\d\d\])\s*(?P<rest>.*?)\s*$")
FRAME = re.compile(
    r"^(?:(?P<sent>=>\s*Poll|Poll|=>)|(?P<received><=\s*Response|Response|<=))\s*:\s*(?P<hex>.*)$",
    re.I,
)


def parse_cas(lines: Lines, where: str, parsed: ParsedLog) -> Iterator[LogRecord]:
    parsed.labels = Labels.HINT
    parsed.client = "CAS_Modbus_Scanner"
    parsed.channel_label = "CAS Modbus Scanner (=> Poll: sent, <= Response: received)"
    order = _Order()
    for number, raw_line in lines():
        yield from order.watch(parsed.flush())
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
    yield from order.watch(parsed.flush())
    if order.newest_first():
        parsed.reverse = True
        parsed.notes.append(
            f"{where}: CAS Modbus Scanner writes the newest line first; its "
            f"{order.count} line(s) are read from the last to the first, in time order"
        )


class _Order:
    """Whether the records run newest first, told as they pass (`watch`): the times
    fall down the file more often than they rise (a fall of more than half a day is
    midnight passed the other way); with no step either way, the first frame is a
    response and the last one a poll."""

    def __init__(self) -> None:
        self.count = 0
        self.falls = self.rises = 0
        self.before: float | None = None
        self.frames = 0
        self.first: Direction | None = None
        self.last: Direction | None = None

    def watch(self, records: Iterator[LogRecord]) -> Iterator[LogRecord]:
        for record in records:
            self.count += 1
            if record.stamp is not None:
                after = record.stamp.seconds
                if self.before is not None:
                    step = after - self.before
                    if step > DAY / 2:
                        step -= DAY
                    elif step < -DAY / 2:
                        step += DAY
                    self.falls += step < 0
                    self.rises += step > 0
                self.before = after
            if record.data:
                self.frames += 1
                if self.first is None:
                    self.first = record.direction
                self.last = record.direction
            yield record

    def newest_first(self) -> bool:
        if self.falls != self.rises:
            return self.falls > self.rises
        return self.frames >= 2 and self.first == Direction.SLAVE and self.last == Direction.MASTER
