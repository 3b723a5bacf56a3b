"""The heap is frozen before a capture is read only when modscope runs as the program."""

from __future__ import annotations

import gc

import pytest

from sniffer.cli import heap, main


def test_settle_freezes_only_as_the_program(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(heap, "_program", False)
    before = gc.get_freeze_count()
    heap.settle()  # a library call (this test process): nothing frozen
    assert gc.get_freeze_count() == before
    heap.as_program()
    try:
        heap.settle()
        assert gc.get_freeze_count() > before
    finally:
        gc.unfreeze()


def test_main_is_the_program_only_with_the_process_arguments(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(heap, "_program", False)
    with pytest.raises(SystemExit):
        main(["--version"])
    assert not heap._program
    monkeypatch.setattr("sys.argv", ["modscope", "--version"])
    with pytest.raises(SystemExit):
        main()
    assert heap._program
    assert "modscope" in capsys.readouterr().out
