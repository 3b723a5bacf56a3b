"""The status bar: the state first, whole parts only, and a colour per state at 80 columns."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from sniffer.tui.widgets.status import SHORTER, StatusInfo, state_of, status_parts, status_text

BASE = StatusInfo(
    source="modscope-capture-of-the-pump-station.pcapng",
    line="19200 8E1 rtu",
    rows=1_562_000,
    bytes=24_800_000,
    errors=3,
    rate=26.1,
    indexing=False,
    paused=False,
    following=False,
)


def with_(**kw: object) -> StatusInfo:
    fields = {name: getattr(BASE, name) for name in StatusInfo.__slots__}
    fields.update(kw)
    return StatusInfo(**fields)


def test_a_recording_live_line_shows_state_file_size_and_losses_at_80_columns() -> None:
    info = with_(
        live=True,
        following=True,
        recording="modscope-20240615-021733.pcapng",
        recorded_bytes=1_234_567,
        losses=0,
        source="/dev/serial/by-id/usb-FTDI_FT232R_USB_UART_A50285BI-if00-port0",
    )
    text = status_text(info, 78).plain
    # the recording's name gives way first, so the counts and the port stay
    assert text == "LIVE ▼ │ ● rec 1.2MB │ lost 0B │ 1,562,000 fr │ 26.1 fr/s │ /dev/se…00-port0"
    assert status_text(info, 160).plain.startswith(
        "LIVE ▼ │ ● rec modscope-20240615-021733.pcapng 1.2MB │ lost 0B"
    )


def test_each_state_names_itself_first() -> None:
    cases = {
        "PAUSED": with_(paused=True, live=True),
        "INDEXING 45%": with_(indexing=True, progress=0.45),
        "INDEXING…": with_(indexing=True),
        "RECONNECTING": with_(live=True, reconnecting=True, paused=True),
        "REPLAY 1x ▼": with_(speed="1x", following=True),
        "STOPPED": with_(note="OSError: [Errno 5] Input/output error"),
    }
    for word, info in cases.items():
        assert status_text(info, 78).plain.startswith(word + " │"), word
    assert state_of(cases["RECONNECTING"]) == "reconnecting"


def test_why_the_feed_stopped_is_shown_before_the_counts() -> None:
    info = with_(note="RuntimeError: pcapng block at offset 812 is cut short")
    text = status_text(info, 78).plain
    assert text.startswith("STOPPED │ RuntimeError: pcapng block at offset 812")


@given(
    width=st.integers(20, 200),
    rows=st.integers(0, 10**9),
    errors=st.integers(0, 10**7),
    rate=st.none() | st.floats(0, 1e6),
    recording=st.text(max_size=80),
    losses=st.integers(0, 10**10),
)
def test_parts_are_whole_or_left_out_never_cut(
    width: int, rows: int, errors: int, rate: float | None, recording: str, losses: int
) -> None:
    info = with_(rows=rows, errors=errors, rate=rate, recording=recording, losses=losses)
    text = status_text(info, width).plain
    assert len(text) <= width
    # the state may be cut at 20 columns; every other part is one of the bar's parts,
    # whole, as it is or as one of the SHORTER steps gives it
    known = {p for level in range(len(SHORTER) + 1) for p in status_parts(info, level)}
    for part in text.split(" │ ")[1:]:
        assert part in known
