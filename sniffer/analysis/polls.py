"""Provides the one rule of what makes two requests the same poll, which the poll cycle
(`sniffer.analysis.pollcycle`: `--stats`, live summaries), the units pane
(`sniffer.tui.widgets.units`) and the compiled core (sniffer/_core.c: poll_block, handed
`core_rules()`) all follow.

A request's poll identity is what it asks of its unit: the function, the address and
the quantity; the values a write carries are left out, so a master that writes changing
values to the same registers polls them as steadily as one that reads them. Where the
dissector reads no address in a request (other function codes, damaged requests), the
identity is its bytes after the function code. The unit is not part of it: every user
groups by unit first.

Requests of the data tables (reads, single and multiple writes: FC 1-6, 15 and 16 of
the public registry) are read straight from their bytes by `RULES`, taken from the
registry's specs (their family, table and quantity limits), because a master that writes
ever new values makes a new body each time and dissecting each is what would cost;
anything else is dissected. tests/analysis/test_pollcycle.py holds the two readings equal.

`frame_body` is a stored row's body whatever its envelope (RTU, ASCII, Modbus TCP), as
`sniffer.framing.store.FrameView.body` gives it.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass

from dissectors import mbap
from dissectors.dissect import dissect
from dissectors.envelope import ascii_body
from dissectors.functions import FUNCTIONS, Registry
from dissectors.pdu.access import COIL_STATES
from dissectors.pdu.work import BIT_TABLES
from dissectors.values import Role
from sniffer.vocab import Flag

Identity = tuple[object, ...]


class Form(enum.IntEnum):
    """How the requests of a function code are laid out, where the rule reads them."""

    READ = 1  # address, quantity
    SINGLE = 2  # address, one value
    MULTIPLE = 3  # address, quantity, byte count, values


_FORMS = {"read": Form.READ, "write_single": Form.SINGLE, "write_multiple": Form.MULTIPLE}


@dataclass(frozen=True, slots=True)
class Rule:
    """How the requests of one function code are read straight from their bytes."""

    code: int
    form: Form
    table: str  # the data table it reads or writes
    # the quantities its requests may carry (the registry's limits); only a multiple
    # write's are checked: where its byte count does not fit them, the dissector is asked
    low: int = 0
    high: int = 0xFFFF
    values: frozenset[int] | None = None  # the values a single write may carry (None: any)

    @property
    def bits(self) -> bool:
        """A table of bits: eight values a byte, where registers take two bytes each."""
        return self.table in BIT_TABLES

    def value_bytes(self, quantity: int) -> int:
        """The bytes `quantity` values of its table take."""
        return (quantity + 7) // 8 if self.bits else 2 * quantity


def rules(registry: Registry = FUNCTIONS) -> dict[int, Rule]:
    """The rule of each code of `registry` whose requests read or write a data table."""
    found: dict[int, Rule] = {}
    for code, spec in registry.items():
        form = _FORMS.get(spec.family)
        if form is None or spec.table is None:
            continue
        quantity = next((limit for limit in spec.limits if limit.field == "quantity"), None)
        low, high = (quantity.low, quantity.high) if quantity is not None else (0, 0xFFFF)
        values = None
        if form == Form.SINGLE and spec.table in BIT_TABLES:
            values = frozenset(COIL_STATES)
        found[code] = Rule(code, form, spec.table, low, high, values)
    return found


# the public registry's, which `dissect` reads requests with
RULES = rules()
_BY_CODE: tuple[Rule | None, ...] = tuple(RULES.get(code) for code in range(256))
_READ_TABLES = {code: r.table for code, r in RULES.items() if r.form == Form.READ}
_WRITES = frozenset(code for code, r in RULES.items() if r.form != Form.READ)

_TABLE_WORDS = {
    "holding_registers": "holding",
    "input_registers": "input",
    "coils": "coil",
    "discrete_inputs": "input bit",
}


def poll_identity(body: bytes) -> tuple[Identity, str]:
    """The identity of the request whose body (unit byte and PDU) is `body`, and a short
    description of it: "read holding 3200-3211", "write coil 16", "FC 8"."""
    return plain_identity(body) or dissected_identity(body)


def plain_identity(body: bytes) -> tuple[Identity, str] | None:
    """`dissected_identity` of a well-formed request of a code in `RULES`, read straight
    from its bytes; None for anything else."""
    size = len(body)
    if size < 6:
        return None
    rule = _BY_CODE[body[1]]
    if rule is None:
        return None
    form = rule.form
    if size == 6:
        if form == Form.READ:
            count = (body[4] << 8) | body[5]
        elif form == Form.SINGLE and (
            rule.values is None or ((body[4] << 8) | body[5]) in rule.values
        ):
            count = 1
        else:
            return None
    elif form == Form.MULTIPLE and size == 7 + body[6]:
        count = (body[4] << 8) | body[5]
        if not (rule.low <= count <= rule.high and body[6] == rule.value_bytes(count)):
            return None
    else:
        return None
    start = (body[2] << 8) | body[3]
    return (rule.code, start, count), _describe(rule.code, rule.table, start, count)


def dissected_identity(body: bytes) -> tuple[Identity, str]:
    """`poll_identity` as the dissector reads the request: any function code, any damage."""
    d = dissect(body, Role.REQUEST)
    address = d.field("address")
    quantity = d.field("quantity")
    start = address.value if address is not None and isinstance(address.value, int) else None
    count = quantity.value if quantity is not None and isinstance(quantity.value, int) else None
    table = _READ_TABLES.get(d.function) or (d.data[0].table if d.data else None)
    if count is None and d.data:
        count = len(d.data[0].values)
    if table is None or start is None:
        return (d.function, body[2:]), f"FC {d.function}"
    return (d.function, start, count), _describe(d.function, table, start, count)


def _describe(function: int, table: str, start: int, count: int | None) -> str:
    word = _TABLE_WORDS.get(table, table)
    span = f"{start}" if not count or count == 1 else f"{start}-{start + count - 1}"
    verb = "write" if function in _WRITES else "read"
    return f"{verb} {word} {span}"


_MBAP, _ASCII = int(Flag.MBAP), int(Flag.ASCII)
FRAMED_APART = _ASCII | _MBAP  # rows whose body is not their bytes less the CRC


def frame_body(raw: bytes, flags: int) -> bytes:
    """The body (unit byte and PDU) of a frame whose stored bytes are `raw` and whose
    flags are `flags`: the MBAP header or the CRC left off, or the ASCII hex decoded and
    its LRC left off (empty when it does not decode), as `FrameView.body` gives it."""
    if flags & _MBAP:
        return mbap.body(raw)
    if flags & _ASCII:
        decoded = ascii_body(raw)
        return decoded[:-1] if decoded else b""
    return raw[:-2]


CoreRule = tuple[int, bool, int, int, bool, tuple[int, ...] | None]


def core_rules(found: Mapping[int, Rule] = RULES) -> tuple[CoreRule, ...]:
    """The rules of the writes, as the compiled core's `poll_table` takes them: for each
    code (code, whether it is a multiple write, its lowest and highest quantity, whether
    its table is of bits, the values a single write may carry or None for any). Reads
    need none there: an RTU read's bytes are already its identity."""
    return tuple(
        (
            r.code,
            r.form == Form.MULTIPLE,
            r.low,
            r.high,
            r.bits,
            None if r.values is None else tuple(sorted(r.values)),
        )
        for r in found.values()
        if r.form != Form.READ
    )
