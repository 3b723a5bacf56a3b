"""The per-server table counts each latency as the figure it prints (`ServerCounts`,
`sniffer.analysis.gateway_report`): the figure must print as the latency itself would,
and order as the latencies do, so that the nearest-rank quantiles of the figures are
the printed quantiles of every value."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from sniffer.analysis.gateway_report import _figure, _figure_text, _ms
from sniffer.analysis.stats import nearest_rank

SECONDS = st.one_of(
    st.floats(-0.01, 0.01),
    st.floats(0, 2e-4),
    st.floats(0, 1e-6),
    st.floats(0, 10),
    st.sampled_from([0.0, -0.0, 1e-4, 5e-7, 0.0001 - 1e-12, 0.00005]),
)


@given(SECONDS)
def test_a_figure_prints_as_its_latency(x: float) -> None:
    assert _figure_text(_figure(x)) == _ms(x)


@given(SECONDS, SECONDS)
def test_figures_order_as_their_latencies(a: float, b: float) -> None:
    if a <= b:
        assert _figure(a) <= _figure(b)


@given(st.lists(SECONDS, min_size=1, max_size=60), st.sampled_from([0.0, 0.5, 0.95, 1.0]))
def test_the_quantile_of_the_figures_is_the_printed_quantile(values: list[float], q: float) -> None:
    figures = sorted(_figure(x) for x in values)
    rank = min(len(figures) - 1, max(0, round(q * (len(figures) - 1))))
    assert _figure_text(figures[rank]) == _ms(nearest_rank(values, q))
