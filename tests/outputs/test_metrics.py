"""`--metrics`: Prometheus metrics of `replay`, `live` and `record`.

The end-to-end check runs a real Prometheus server (Debian's `prometheus`) scraping a
`modscope replay --metrics` of the demo every second, asks its HTTP API for the figures
and compares them with `modscope replay --stats` of the same capture. The rest reads the
exposition with prometheus_client's own parser."""

from __future__ import annotations

import importlib.util
import json
import re
import signal
import socket
import subprocess
import sys
import time
import urllib.parse
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from sniffer.analysis.stats import RECENT, UnitStats
from sniffer.cli import main
from sniffer.meaning.annotate import load_bindings
from sniffer.model import Chunk, LineSettings, Stamp
from sniffer.outputs.metrics import BUCKETS, Metrics, MetricsError, _Latencies, parse_listen
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, Session, open_session
from tests.conftest import find_program
from tests.support.virtual_bus import VirtualBus, wait_ready

prometheus_client = pytest.importorskip("prometheus_client")
from prometheus_client.parser import text_string_to_metric_families  # noqa: E402
from prometheus_client.registry import CollectorRegistry  # noqa: E402

MODSCOPE = str(Path(sys.executable).with_name("modscope"))
Samples = dict[tuple[str, frozenset[tuple[str, str]]], float]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _samples(text: str) -> Samples:
    found: Samples = {}
    for family in text_string_to_metric_families(text):
        for sample in family.samples:
            found[(sample.name, frozenset(sample.labels.items()))] = sample.value
    return found


def _exposition(metrics: Metrics) -> Samples:
    registry = CollectorRegistry(auto_describe=False)
    registry.register(metrics)
    return _samples(prometheus_client.generate_latest(registry).decode())


def _unit(samples: Samples, name: str, **labels: str) -> float:
    return samples[(name, frozenset(labels.items()))]


def _stats_table(text: str) -> dict[str, dict[str, int]]:
    """`replay --stats`: unit -> req, resp, exc, t/o, chk (and exceptions by code)."""
    found: dict[str, dict[str, int]] = {}
    last = ""
    for line in text.splitlines():
        if line.startswith("noise:"):  # the end of the unit table (the poll cycle follows)
            break
        if re.match(r"\s{0,3}\d+  ", line) and len(line) > 24:
            numbers = line[23:].split()[:5]
            last = line[:4].strip()
            found[last] = dict(
                zip(("req", "resp", "exc", "t/o", "chk"), map(int, numbers), strict=True)
            )
        elif "exceptions by code:" in line:
            for code, count in re.findall(r"(\d+) x(\d+)", line):
                found[last][f"code {int(code)}"] = int(count)
    return found


# -- the listening address --------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "host", "port"),
    [
        ("9108", "127.0.0.1", 9108),
        ("0.0.0.0:9108", "0.0.0.0", 9108),
        ("[::1]:9108", "::1", 9108),
        (":0", "127.0.0.1", 0),
        ("localhost:9200", "localhost", 9200),
    ],
)
def test_listen_address(text: str, host: str, port: int) -> None:
    assert parse_listen(text) == (host, port)


@pytest.mark.parametrize("text", ["", "web", "9108:", "1.2.3.4:70000", "-5"])
def test_a_listen_address_that_is_not_one_says_how_to_write_it(text: str) -> None:
    with pytest.raises(MetricsError, match=r"\[HOST:\]PORT"):
        parse_listen(text)


def test_options_that_cannot_be_used_are_plain_errors(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["replay", "--stats", "--metrics-hold", "5"]) == 2
    assert "--metrics-hold keeps the metrics served: give --metrics too" in capsys.readouterr().err
    assert main(["replay", "--stats", "--metrics", "web"]) == 2
    assert "write [HOST:]PORT" in capsys.readouterr().err
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["replay", "--stats", "--metrics", str(port)]) == 2
    err = capsys.readouterr().err
    assert f"--metrics 127.0.0.1:{port}: cannot listen there" in err and "choose another" in err


def test_without_the_extra_metrics_say_what_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    real = importlib.util.find_spec

    def find_spec(name: str, package: str | None = None) -> Any:
        return None if name == "prometheus_client" else real(name, package)

    monkeypatch.setattr(importlib.util, "find_spec", find_spec)
    with pytest.raises(MetricsError, match=r"pip install 'modscope\[metrics\]'"):
        Metrics()


# -- the figures ------------------------------------------------------------------------------


def _demo() -> tuple[Session, Metrics]:
    bindings = load_bindings(DEMO_BUS)
    session, capture = open_session(DEMO_CAPTURE, bindings=bindings)
    metrics = Metrics()
    metrics.watch("demo", session, bindings)
    session.ingest(capture.chunks(), lambda done, rows: metrics.update())
    metrics.update()
    return session, metrics


def test_the_figures_are_those_of_the_statistics() -> None:
    session, metrics = _demo()
    samples = _exposition(metrics)
    stats = session.stats
    frames = sum(u.requests + u.responses + u.check_errors for u in stats.units.values())
    assert samples[("modscope_frames_total", frozenset())] == frames == 1560
    assert samples[("modscope_check_errors_total", frozenset())] == 1
    assert samples[("modscope_noise_bytes_total", frozenset())] == stats.noise_bytes
    assert samples[("modscope_lost_bytes_total", frozenset())] == 0
    for u, figures in stats.units.items():
        unit = str(u)
        assert _unit(samples, "modscope_requests_total", unit=unit) == figures.requests
        assert _unit(samples, "modscope_responses_total", unit=unit) == figures.responses
        assert _unit(samples, "modscope_timeouts_total", unit=unit) == figures.timeouts
        for code, count in figures.exceptions.items():
            assert _unit(samples, "modscope_exceptions_total", unit=unit, code=str(code)) == count
        latencies = sorted(figures.latencies)
        assert _unit(samples, "modscope_response_seconds_count", unit=unit) == len(latencies)
        assert _unit(samples, "modscope_response_seconds_sum", unit=unit) == pytest.approx(
            sum(latencies)
        )
        for bound in BUCKETS:
            below = sum(1 for x in latencies if x <= bound)
            assert _unit(samples, "modscope_response_seconds_bucket", unit=unit, le=str(bound)) == (
                below
            )
    up = {u: _unit(samples, "modscope_unit_up", unit=str(u)) for u in stats.units}
    assert up == {1: 1, 2: 1, 3: 1, 4: 0}  # unit 4 never answers
    assert _unit(samples, "modscope_unit_info", unit="2", device="PF controller", model="dcrl") == (
        1
    )


def test_several_buses_each_get_a_bus_label() -> None:
    metrics = Metrics(several=True)
    bindings = load_bindings(DEMO_BUS)
    for name in ("cabinet1", "cabinet1"):  # the same name twice: two buses all the same
        session, capture = open_session(DEMO_CAPTURE, bindings=bindings)
        metrics.watch(name, session, bindings)
        session.ingest(capture.chunks())
    metrics.update()
    samples = _exposition(metrics)
    assert samples[("modscope_frames_total", frozenset({("bus", "cabinet1")}))] == 1560
    assert samples[("modscope_frames_total", frozenset({("bus", "cabinet1 (2)")}))] == 1560
    assert _unit(samples, "modscope_requests_total", bus="cabinet1 (2)", unit="3") == 282


LINE = LineSettings(baud=19200, bytesize=8, parity="E", stopbits=1, mode="rtu")


def test_an_answer_the_timing_cannot_measure_is_counted_but_never_timed() -> None:
    """A source without timestamps: five answers, no latency. The histogram stays empty
    rather than holding made-up values."""
    session = Session(LINE, stamps=Stamp.NONE)
    metrics = Metrics()
    metrics.watch("bus", session, {})
    request = with_crc(bytes.fromhex("010300000002"))
    answer = with_crc(bytes.fromhex("0103040001000a"))
    for k in range(5):
        session.feed(Chunk(request, 10.0 + k))
        session.feed(Chunk(answer, 10.05 + k))
    session.finish()
    metrics.update()
    samples = _exposition(metrics)
    assert _unit(samples, "modscope_responses_total", unit="1") == 5
    assert _unit(samples, "modscope_response_seconds_count", unit="1") == 0
    assert _unit(samples, "modscope_response_seconds_bucket", unit="1", le="+Inf") == 0


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(0.0001, 3.0), min_size=1, max_size=3000),
    st.lists(st.integers(1, 2500), min_size=1, max_size=6),
    st.booleans(),
)
def test_the_histogram_counts_every_measured_latency_once(
    values: list[float], cuts: list[int], bounded: bool
) -> None:
    """Fed in parts of any size, kept whole or bounded (a live capture: the newest 1,024
    exact, the rest counted to 0.1 ms), every latency is counted once; kept whole, each
    in its very bucket."""
    unit = UnitStats(1)
    if bounded:
        unit.bound()
    histogram = _Latencies()
    at = 0
    for cut in [*cuts, len(values)]:
        part = values[at : at + cut]
        at += len(part)
        if bounded:
            assert unit.tallies is not None
            unit.tallies.add_latencies(part)
        else:
            unit.latencies.extend(part)
        histogram.take(unit)
    assert histogram.count == len(values)
    assert histogram.total == pytest.approx(sum(values), abs=0.00005 * len(values) + 1e-9)
    if not bounded or max(cuts) <= RECENT:
        expected = [0] * (len(BUCKETS) + 1)
        for x in values:
            expected[sum(1 for b in BUCKETS if b < x)] += 1
        assert histogram.buckets == expected


# -- a real Prometheus ------------------------------------------------------------------------


def _get(url: str) -> Any:
    with urllib.request.urlopen(url, timeout=5) as answer:  # (loopback only)
        return json.loads(answer.read().decode()) if "/api/" in url else answer.read()


def _query(web: int, query: str) -> list[dict[str, Any]]:
    found = _get(f"http://127.0.0.1:{web}/api/v1/query?" + urllib.parse.urlencode({"query": query}))
    assert found["status"] == "success", found
    result: list[dict[str, Any]] = found["data"]["result"]
    return result


def _by_unit(web: int, query: str, *keys: str) -> dict[tuple[str, ...], float]:
    return {
        tuple(r["metric"].get(k, "") for k in keys): float(r["value"][1])
        for r in _query(web, query)
    }


@pytest.fixture
def prometheus(tmp_path: Path) -> Iterator[tuple[int, int]]:
    """A Prometheus server on a free loopback port scraping 127.0.0.1:<port> every
    second: (metrics port to serve on, its web port)."""
    program = find_program("prometheus")
    assert program is not None
    port, web = _free_port(), _free_port()
    config = tmp_path / "prometheus.yml"
    config.write_text(
        "global:\n  scrape_interval: 1s\n  scrape_timeout: 1s\n"
        "scrape_configs:\n  - job_name: modscope\n    static_configs:\n"
        f"      - targets: ['127.0.0.1:{port}']\n"
    )
    log = (tmp_path / "prometheus.log").open("w")
    proc = subprocess.Popen(
        [
            program,
            f"--config.file={config}",
            f"--storage.tsdb.path={tmp_path / 'data'}",
            f"--web.listen-address=127.0.0.1:{web}",
        ],
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                _get(f"http://127.0.0.1:{web}/-/ready")
                break
            except OSError:
                if proc.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(
                        "prometheus did not start: " + (tmp_path / "prometheus.log").read_text()
                    ) from None
                time.sleep(0.2)
        yield port, web
    finally:
        proc.terminate()
        proc.wait(30)
        log.close()


@pytest.mark.peer
@pytest.mark.needs("prometheus")
def test_a_real_prometheus_scrapes_what_replay_stats_counts(
    prometheus: tuple[int, int],
) -> None:
    port, web = prometheus
    stats = subprocess.run(
        [MODSCOPE, "replay", "--stats"], capture_output=True, text=True, timeout=120, check=True
    )
    expected = _stats_table(stats.stdout)
    assert set(expected) == {"1", "2", "3", "4"}
    frames = sum(u["req"] + u["resp"] + u["chk"] for u in expected.values())
    replay = subprocess.Popen(
        [MODSCOPE, "replay", "--stats", "--metrics", str(port), "--metrics-hold", "60"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 60
        seen: list[dict[str, Any]] = []
        while time.monotonic() < deadline:
            seen = _query(web, "modscope_frames_total")
            if seen and float(seen[0]["value"][1]) == frames:
                break
            time.sleep(0.3)
        assert seen and float(seen[0]["value"][1]) == frames, seen
        requests = _by_unit(web, "modscope_requests_total", "unit")
        responses = _by_unit(web, "modscope_responses_total", "unit")
        timeouts = _by_unit(web, "modscope_timeouts_total", "unit")
        exceptions = _by_unit(web, "modscope_exceptions_total", "unit", "code")
        timed = _by_unit(web, "modscope_response_seconds_count", "unit")
        every = _by_unit(web, 'modscope_response_seconds_bucket{le="+Inf"}', "unit")
        up = _by_unit(web, "modscope_unit_up", "unit")
        checks = _query(web, "modscope_check_errors_total")
        median = _by_unit(
            web,
            "histogram_quantile(0.5, sum by (unit, le) (modscope_response_seconds_bucket))",
            "unit",
        )
        dashboard = {expr: _query(web, expr) for expr in _dashboard_queries(".*", "5s")}
    finally:
        replay.send_signal(signal.SIGINT)  # (the hold ends at Ctrl-C)
        out, err = replay.communicate(timeout=30)
    assert replay.returncode == 0, err
    assert out == stats.stdout  # the listing is the same with metrics served
    for unit, row in expected.items():
        assert requests[(unit,)] == row["req"]
        assert responses[(unit,)] == row["resp"]
        assert timeouts[(unit,)] == row["t/o"]
        for key, count in row.items():
            if key.startswith("code "):
                assert exceptions[(unit, key.split()[1])] == count
        assert sum(v for (u, _), v in exceptions.items() if u == unit) == row["exc"]
    assert float(checks[0]["value"][1]) == sum(u["chk"] for u in expected.values())
    assert "left out of the latency columns" not in stats.stdout  # every answer was timed
    assert {u: v for (u,), v in timed.items()} == {u: r["resp"] for u, r in expected.items()}
    assert timed == every
    assert up == {("1",): 1, ("2",): 1, ("3",): 1, ("4",): 0}
    # the median bucket holds --stats' median: unit 3 answers in 7.2 ms, between 5 and 10
    assert 0.005 <= median[("3",)] <= 0.01
    # every query of the Grafana dashboard runs (a PromQL error fails _query); the units
    # panel names the four units
    units = [r for e, r in dashboard.items() if "modscope_unit_up" in e]
    assert {r["metric"]["unit"] for r in units[0]} == {"1", "2", "3", "4"}


# -- the Grafana dashboard

DASHBOARD = Path(__file__).resolve().parents[2] / "docs" / "grafana-modscope.json"


def _dashboard_queries(instance: str, interval: str) -> list[str]:
    dashboard = json.loads(DASHBOARD.read_text())
    return [
        t["expr"].replace("$__rate_interval", interval).replace("$instance", instance)
        for p in dashboard["panels"]
        for t in p["targets"]
    ]


def test_the_dashboard_shows_what_modscope_serves() -> None:
    dashboard = json.loads(DASHBOARD.read_text())
    titles = [p["title"] for p in dashboard["panels"]]
    for words in ("Frames", "Requests", "Exceptions", "Timeouts", "Answer time", "Units up"):
        assert any(words in t for t in titles), words
    _, metrics = _demo()
    served = {name for name, _ in _exposition(metrics)}
    named = set(re.findall(r"modscope_\w+", " ".join(_dashboard_queries(".*", "1m"))))
    assert named and named <= served, named - served


# -- live and record --------------------------------------------------------------------------


@pytest.mark.peer
@pytest.mark.parametrize("command", ["live", "record"])
def test_live_and_record_serve_the_line_as_it_runs(tmp_path: Path, command: str) -> None:
    request = with_crc(bytes.fromhex("010300000002"))
    answer = with_crc(bytes.fromhex("0103040001000a"))
    port = _free_port()
    extra = ["--format", "jsonl"] if command == "live" else ["-w", str(tmp_path / "rec.pcapng")]
    extra += ["--metrics", str(port)]
    with VirtualBus(tmp_path) as bus:
        tap = bus.attach("tap")
        bus.attach("master")
        bus.attach("slave")
        proc = subprocess.Popen(
            [MODSCOPE, command, str(tap), "--parity", "N", "--stopbits", "2", *extra],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            assert proc.stderr is not None
            said = wait_ready(proc.stderr)
            assert f"modscope: serving metrics at http://127.0.0.1:{port}/metrics\n" in said
            for _ in range(5):
                bus.inject(request, source="master")
                time.sleep(0.02)
                bus.inject(answer, source="slave")
                time.sleep(0.2)
            deadline = time.monotonic() + 20
            samples: Samples = {}
            while time.monotonic() < deadline:
                samples = _samples(_get(f"http://127.0.0.1:{port}/metrics").decode())
                if samples.get(("modscope_responses_total", frozenset({("unit", "1")}))) == 5:
                    break
                time.sleep(0.2)
        finally:
            proc.send_signal(signal.SIGINT)
            _, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert _unit(samples, "modscope_requests_total", unit="1") == 5
    assert _unit(samples, "modscope_responses_total", unit="1") == 5
    assert _unit(samples, "modscope_unit_up", unit="1") == 1
    assert samples[("modscope_frames_total", frozenset())] == 10
    assert samples[("modscope_lost_bytes_total", frozenset())] == 0
    assert "metrics: " in err and "scrapes of" in err
