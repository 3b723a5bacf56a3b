"""The man page has the sections a man page is read for (EXIT STATUS, ENVIRONMENT,
FILES, SEE ALSO), lists exactly the parser's options per command, and names every
environment variable the code reads (issue 26)."""

from __future__ import annotations

import ast
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from sniffer.cli.manual import _commands, man_page
from sniffer.cli.parser import build_parser

ROOT = Path(__file__).resolve().parent.parent.parent


def _sections(page: str) -> dict[str, str]:
    """The page's .SH sections by title, and each command's .SS block as `COMMAND name`."""
    out: dict[str, str] = {}
    title = section = ""
    for line in page.splitlines():
        if line.startswith(".SH "):
            title = section = line[4:].strip('"')
            out[title] = ""
        elif line.startswith(".SS ") and section == "COMMANDS":
            title = "COMMAND " + line[4:].replace("\\-", "-")
            out[title] = ""
        elif title:
            out[title] += line + "\n"
    return out


def test_the_page_has_the_sections_people_look_for() -> None:
    sections = _sections(man_page(build_parser()))
    for title in ("NAME", "SYNOPSIS", "DESCRIPTION", "EXIT STATUS", "ENVIRONMENT", "FILES"):
        assert sections.get(title, "").strip(), title
    assert "SEE ALSO" in sections and "tshark" in sections["SEE ALSO"]
    status = sections["EXIT STATUS"]
    for code in ("0", "1", "2", "70", "130"):
        assert f"\\fB{code}\\fR" in status


def test_each_command_lists_exactly_its_options() -> None:
    parser = build_parser()
    sections = _sections(man_page(parser))
    for name, sub in _commands(parser):
        listed = set(re.findall(r"\\fB(\\-[^\\]*(?:\\-[^\\]*)*)\\fR", sections[f"COMMAND {name}"]))
        listed = {o.replace("\\-", "-") for o in listed}
        options = {
            o
            for a in sub._actions
            if a.option_strings and a.help != "==SUPPRESS==" and a.dest != "help"
            for o in a.option_strings
        }
        assert listed == options, name


def _variables_read() -> set[str]:
    """Every MODSCOPE_* or XDG_* name written as a string in the code."""
    found: set[str] = set()
    for folder in ("sniffer", "dissectors"):
        for path in (ROOT / folder).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if (
                    isinstance(node, ast.Constant)
                    and isinstance(node.value, str)
                    and re.fullmatch(r"(MODSCOPE|XDG)_[A-Z_]+", node.value)
                ):
                    found.add(node.value)
    return found


def test_every_environment_variable_the_code_reads_is_in_the_page() -> None:
    read = _variables_read()
    assert {"MODSCOPE_NO_INDEX", "MODSCOPE_MQTT_USER", "XDG_CACHE_HOME"} <= read
    environment = _sections(man_page(build_parser()))["ENVIRONMENT"].replace("\\-", "-")
    assert {v for v in read if v not in environment} == set()


@pytest.mark.skipif(shutil.which("man") is None, reason="needs man (apt-get install man-db)")
def test_man_renders_the_page_without_complaint(tmp_path: Path) -> None:
    page = tmp_path / "modscope.1"
    page.write_text(man_page(build_parser()))
    done = subprocess.run(
        ["man", "--warnings", "-l", str(page)],
        capture_output=True,
        text=True,
        env={"MANWIDTH": "100", "PATH": "/usr/bin:/bin", "LANG": "C.UTF-8"},
        timeout=60,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "EXIT STATUS" in done.stdout and "SEE ALSO" in done.stdout
    assert done.stderr == "", done.stderr
