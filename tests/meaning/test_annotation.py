"""Annotation: the seed manuals' worked examples mean what the manuals say, and the demo
capture shows names, units, windows and the devices' own timing rules."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from dissectors.dictionary import load_dictionary, load_model
from sniffer.meaning.annotate import Binding, load_bindings
from sniffer.model import Chunk, LineSettings, Stamp
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, Session, replay_file
from sniffer.vocab import Flag, Kind, Status
from tests.support.seedvectors import MODELS, by_id, load_examples, wire_bytes

TUTORIAL = Path(__file__).parent.parent / "fixtures" / "tutorial" / "ved903b-tutorial.toml"
EXAMPLES = load_examples()
BY_ID = by_id(EXAMPLES)
WITH_MEANING = [e for e in EXAMPLES if e.get("registers")]

# Printed bytes that contradict the meaning the manual states for them. modscope shows
# the bytes as sent with the problem; the stated meaning cannot be read from them.
CONTRADICTED = {
    "rvs-dn-ex7-force-coils-req": "byte count 1 and data 00 07: the coils are written OFF",
}


def _request_misprinted(example: dict[str, Any]) -> bool:
    """A response whose printed request has a wrong check: a master would not have sent
    it, and a sniffer cannot pair the answer with it."""
    request = BY_ID.get(str(example.get("pairs_with", "")))
    return request is not None and not request["check_ok"]


def _dictionary_for(example: dict[str, Any]) -> Any:
    model = load_model(MODELS[example["_file"]])
    names = {e.name for e in model.entries}
    names |= {p.name for w in model.windows for p in w.parameters.values()}
    if all(r["name"] in names for r in example["registers"]):
        return model
    return load_dictionary(TUTORIAL)  # the tutorial's generic addresses


def _capture_for(example: dict[str, Any]) -> list[dict[str, Any]]:
    """The frames a bus would have carried up to this example: the earlier examples of
    the same manual, unit and mode (they select parameter windows), in printed order."""
    same = [
        e
        for e in EXAMPLES
        if e["_file"] == example["_file"]
        and e.get("mode") == example.get("mode")
        and e["unit"] == example["unit"]
        and e.get("check_ok")
    ]
    upto = same[: same.index(example) + 1] if example in same else [*same, example]
    return upto


def _session(frames: list[dict[str, Any]], dictionary: Any, unit: int, mode: str) -> Session:
    line = LineSettings(mode=mode)
    session = Session(line, bindings={unit: Binding(unit, dictionary.name, dictionary)})
    t = 100.0
    for e in frames:
        data = wire_bytes(e)
        t += len(data) * line.char_time + (0.01 if e["role"] != "request" else 0.05)
        session.feed(Chunk(data, t_end=t))
    session.finish()
    return session


def _value_matches(got: Any, want: Any) -> bool:
    if isinstance(want, float) or isinstance(got, float):
        return isinstance(got, int | float) and abs(float(got) - float(want)) < 1e-6
    return bool(got == want)


@pytest.mark.parametrize("example", WITH_MEANING, ids=[str(e["id"]) for e in WITH_MEANING])
def test_worked_example_annotates_to_the_meaning_the_manual_states(example: dict[str, Any]) -> None:
    dictionary = _dictionary_for(example)
    mode = str(example.get("mode", "rtu"))
    session = _session(_capture_for(example), dictionary, int(example["unit"]), mode)
    store = session.store
    raw = wire_bytes(example)
    rows = [i for i in range(len(store)) if store.raw(i) == raw]
    assert rows, f"{example['id']} was not framed"
    detail = session.describer.detail(rows[-1])
    if example["id"] in CONTRADICTED:
        assert detail.problems, CONTRADICTED[str(example["id"])]
        return
    if _request_misprinted(example):
        # unpaired: the answer's address is unknown, so nothing is guessed; its meaning
        # is checked at the address the manual says it has
        assert detail.registers == ()
        values = detail.dissection.data[0].values if detail.dissection else ()
        start = min(r["address"] for r in example["registers"])
        decoded = dictionary.decode(example["registers"][0]["table"], start, list(values))
        got = {(r.table, r.address, r.name): r for r in decoded}
    else:
        got = {(r.table, r.address, r.name): r for r in detail.registers}
    for want in example["registers"]:
        key = (want["table"], want["address"], want["name"])
        assert key in got, f"{key} not in {sorted(got)}"
        r = got[key]
        assert _value_matches(r.value, want["value"]), (key, r.value, want["value"])
        assert r.unit == want.get("unit", "")
        assert want["name"] in r.text


# -- the demo capture ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def demo() -> Session:
    return replay_file(DEMO_CAPTURE, bindings=load_bindings(DEMO_BUS))


def _summaries(session: Session, unit: int, kind: Kind) -> list[str]:
    store = session.store
    return [
        session.describer.detail(i).summary
        for i in range(len(store))
        if store.unit[i] == unit and store.kind[i] == kind
    ]


def test_demo_rvs_dn_values_have_names_units_and_bit_meanings(demo: Session) -> None:
    answers = _summaries(demo, 3, Kind.RESPONSE)
    assert any("Logic Status = Motor is running" in s and "Voltage = 4" in s for s in answers)
    assert any("Under Voltage Trip = 300 V" in s for s in answers)


def test_demo_dcrl_cos_phi_sign_and_magnitude_and_window_parameter(demo: Session) -> None:
    answers = _summaries(demo, 2, Kind.RESPONSE)
    assert any("Actual cos-phi = 95 inductive" in s for s in answers)
    assert any("Actual cos-phi = 95 capacitive" in s for s in answers)
    assert any("Panel temperature = 28 °C" in s for s in answers)
    # the value read at 5004h after 1 was written to 5002h is parameter P.01
    assert any(s.endswith("P.01 = 250") for s in answers)


def test_demo_ved903b_low_word_first_floats(demo: Session) -> None:
    answers = _summaries(demo, 1, Kind.RESPONSE)
    assert any("04.4/A: Under Excitation Trip = 5.0 %" in s for s in answers)


def test_demo_write_outside_the_range_is_flagged_and_explains_the_exception(demo: Session) -> None:
    store = demo.store
    rows = [
        i
        for i in range(len(store))
        if store.unit[i] == 3 and store.fc[i] == 6 and store.kind[i] == Kind.REQUEST
    ]
    refused = [i for i in rows if store.status[i] == Status.EXCEPTION]
    assert len(refused) == 1
    request = demo.describer.detail(refused[0])
    assert "Under Voltage Trip: written value 700 V above the documented maximum 600 V" in (
        request.problem_texts
    )
    answer = demo.describer.detail(store.partner[refused[0]])
    assert "exception 03 illegal data value" in answer.summary
    assert "explained by the request: written value 700 V above the documented maximum" in (
        answer.summary
    )


def test_demo_device_timing_rules(demo: Session) -> None:
    store = demo.store
    slow = [i for i in range(len(store)) if store.flags[i] & Flag.DEVICE_SLOW]
    assert slow and all(store.unit[i] == 3 for i in slow)
    text = demo.describer.detail(slow[0]).problem_texts
    assert any("the device normally answers within 40 ms" in p for p in text)
    quiet = [i for i in range(len(store)) if store.flags[i] & Flag.QUIET_VIOLATED]
    assert quiet and all(store.unit[i] == 3 and store.kind[i] == Kind.REQUEST for i in quiet)
    first_write = min(i for i in range(len(store)) if store.unit[i] == 3 and store.fc[i] == 6)
    assert all(store.t[i] - store.t[first_write] < 1.1 for i in quiet[:3])


def test_unbound_units_show_raw_values(demo: Session) -> None:
    store = demo.store
    row = next(i for i in range(len(store)) if store.unit[i] == 4)
    detail = demo.describer.detail(row)
    assert detail.registers == () and detail.label == ""


def test_vendor_function_is_framed_from_its_layout_and_its_answered_broadcast_paired() -> None:
    """VED903B 0x41 Get Slave Address: sent to address 0, answered by the unit. Its
    layout in the dictionary frames it even with no silence to go by."""
    ved = load_model("ved903b")
    req = wire_bytes(BY_ID["ved903b-fc41-req"])
    resp = wire_bytes(BY_ID["ved903b-fc41-resp"])
    poll = bytes.fromhex("01030000000a")
    from dissectors.checks import with_crc

    session = Session(LineSettings(mode="rtu"), bindings={1: Binding(1, "Exciter", ved)})
    session.feed(Chunk(req + resp + with_crc(poll), t_end=1.0))
    session.finish()
    store = session.store
    assert [store.raw(i) for i in range(len(store))] == [req, resp, with_crc(poll)]
    assert store.status[0] == store.status[1] == Status.OK and store.partner[1] == 0
    assert not store.flags[1] & Flag.ANSWERED_BROADCAST
    detail = session.describer.detail(1)
    assert detail.name == "Get Slave Address"
    assert "Slave address = 1" in detail.summary
    # without the dictionary the same bytes are an unknown code: noise, not a guess
    bare = Session(LineSettings(mode="rtu"))
    bare.feed(Chunk(req + resp + with_crc(poll), t_end=1.0))
    bare.finish()
    assert Kind.NOISE in {Kind(k) for k in bare.store.kind}


@pytest.mark.parametrize(
    ("after", "said"),
    [
        # 0.1 s stamps: 120 ms is only a bound (<0.2 s), so no slower than 40 ms for sure
        (0.12, None),
        # 250 ms is 150-350 ms: slow, but maybe within the long answers' 200 ms
        (0.25, "answer after 250 ms; the device normally answers within 40 ms (long answers"),
        # 400 ms is 300-500 ms: beyond 200 ms for sure (and not late: the 347 ms timeout
        # plus the 100 ms the stamps may be off is 447 ms)
        (0.40, "answer after 400 ms, beyond the longest response time the device documents"),
    ],
)
def test_a_slow_answer_is_one_the_stamps_show_slow(
    demo: Session, after: float, said: str | None
) -> None:
    """The demo's RVS-DN (unit 3) documents 40 ms, long answers up to 200 ms; its answer
    replayed `after` seconds after its request, stamped to 0.1 s. Slower than a
    documented time only where every latency the stamps allow is."""
    store = demo.store
    answer = next(i for i in range(len(store)) if store.flags[i] & Flag.DEVICE_SLOW)
    request = store.partner[answer]
    req, ans = store.raw(request), store.raw(answer)
    session = Session(
        demo.line, bindings=load_bindings(DEMO_BUS), stamps=Stamp.READ_END, resolution=0.1
    )
    end = 10.0 + after + len(ans) * demo.line.char_time
    session.ingest([Chunk(req, 10.0), Chunk(ans, end), Chunk(req, 11.0)])
    replayed = session.store
    assert [replayed.kind[k] for k in range(2)] == [Kind.REQUEST, Kind.RESPONSE]
    slow = bool(replayed.flags[1] & Flag.DEVICE_SLOW)
    problems = session.describer.detail(1).problem_texts
    if said is None:
        assert not slow and problems == ()
    else:
        assert slow and len(problems) == 1 and problems[0].startswith(said)
