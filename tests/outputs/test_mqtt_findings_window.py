"""The `findings` message says which rows the doctor read: a session that keeps its
memory bounded (a headless live capture) holds only its current segment, and the
message names that segment rather than seeming to speak of the whole capture."""

from __future__ import annotations

import json

from sniffer.outputs.mqtt.findings import findings_payload
from sniffer.session.session import DEMO_CAPTURE, Session, open_session


def test_findings_name_the_segment_they_read() -> None:
    session, capture = open_session(DEMO_CAPTURE, index=False)
    session.batch_reads = False  # (a small file's reads framed as one batch: no cut)
    said: list[tuple[int, int, dict[str, object]]] = []

    def segment(s: Session) -> None:
        said.append((s.base, len(s.store), json.loads(findings_payload(s, {}))))

    session.ingest(capture.chunks(), window=300, segment=segment)
    assert len(said) >= 3  # several segments, then the last one at the end
    for base, rows, message in said:
        assert (message["first_row"], message["rows"]) == (base, rows)
    assert said[0][0] == 0 and said[-1][0] > 0
    assert [b for b, _, _ in said] == sorted({b for b, _, _ in said})
