"""Provides `--metrics [HOST:]PORT` (and `replay --metrics-hold S`): the options, and the
server the commands open (see `sniffer.outputs.metrics` and docs/metrics.md)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any, TextIO

from sniffer.errors import UsageError
from sniffer.outputs.metrics import Fanout, Metrics, MetricsError, MetricsFeed, parse_listen


def add_metrics_options(p: argparse.ArgumentParser, *, replay: bool = False) -> None:
    g = p.add_argument_group(
        "Prometheus metrics (pip install 'modscope[metrics]'; see docs/metrics.md)"
    )
    g.add_argument(
        "--metrics",
        metavar="[HOST:]PORT",
        help="serve Prometheus metrics at http://HOST:PORT/metrics while reading (host "
        "127.0.0.1 unless given; 0.0.0.0 for every interface; port 0 takes a free one)",
    )
    if replay:
        g.add_argument(
            "--metrics-hold",
            type=float,
            default=0.0,
            metavar="S",
            help="keep serving the metrics S seconds after the end of the capture, so that "
            "a scrape reads the totals (Ctrl-C ends it sooner)",
        )


def open_metrics(args: argparse.Namespace, err: TextIO, *, several: bool = False) -> Metrics | None:
    """The metrics server `--metrics` asks for, serving already (None without it)."""
    hold = getattr(args, "metrics_hold", 0.0) or 0.0
    if not getattr(args, "metrics", None):
        if hold:
            raise UsageError("--metrics-hold keeps the metrics served: give --metrics too")
        return None
    if hold < 0:
        raise UsageError(f"--metrics-hold must be 0 or more seconds, not {hold:g}")
    try:
        host, port = parse_listen(args.metrics)
        metrics = Metrics(several=several)
        url = metrics.serve(host, port)
    except MetricsError as exc:
        raise UsageError(str(exc)) from None
    err.write(f"modscope: serving metrics at {url}\n")
    err.flush()
    return metrics


def reading_with(
    metrics: Metrics | None, reading: Callable[[int, int], None]
) -> Callable[[int, int], None]:
    """A replay's progress callback (called after each refresh of the session) that takes
    the metrics' figures too."""
    if metrics is None:
        return reading

    def both(done: int, rows: int) -> None:
        reading(done, rows)
        metrics.update()

    return both


def live_outputs(publisher: Any, metrics: Metrics | None) -> Any:
    """What a live capture feeds: the MQTT publisher, the metrics, both, or None."""
    if metrics is None:
        return publisher
    feed = MetricsFeed(metrics)
    return feed if publisher is None else Fanout([publisher, feed])


def finish_metrics(metrics: Metrics | None, hold: float = 0.0) -> None:
    """The last figures, served `hold` seconds more, then the server closed."""
    if metrics is None:
        return
    try:
        metrics.update()
        if hold > 0:
            metrics.hold(hold)
    finally:
        metrics.close()
