"""Provides `modscope dict`: list the shipped device models, show one, check files, and
draft a dictionary for an unknown unit from a capture."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TextIO

from dissectors.dictionary import (
    builtin_models,
    check_dictionary,
    describe,
    file_format,
    load_dictionaries,
    load_dictionary,
    load_model,
)
from dissectors.dictionary.loader import FORMAT_NAMES
from sniffer.analysis.draft import guesses, observe, summary, toml_of, units_seen
from sniffer.cli.options import SubParsers, add_line_options, read_options
from sniffer.errors import UsageError
from sniffer.session.session import open_session
from sniffer.text import plain, plain_lines

DRAFT_EPILOG = """\
examples:
  modscope dict draft site.pcapng --unit 7 -o pump.toml
  modscope dict check pump.toml
  modscope replay site.pcapng --dict pump.toml      (the draft binds unit 7 by itself)
"""


def cmd_dict(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    if args.action == "list":
        for name, path in sorted(builtin_models().items()):
            d = load_dictionary(path)
            out.write(f"{plain(name):<12} {plain(d.name)}  ({len(d.entries)} entries)\n")
        return 0
    if args.action == "check":
        bad = 0
        for file in args.files:
            problems = check_dictionary(file)
            if problems:
                for problem in problems:
                    err.write(f"{plain_lines(str(problem))}\n")
                many = f"{len(problems)} problems" if len(problems) > 1 else "1 problem"
                err.write(f"{plain(file)}: {many}\n")
                bad += 1
                continue
            found = load_dictionaries(file)
            kind = FORMAT_NAMES[file_format(file)]
            models = ", ".join(f"{plain(d.model)} ({len(d.entries)} entries)" for d in found)
            out.write(f"{plain(file)}: ok, {kind}: {models}\n")
        return 1 if bad else 0
    if args.action == "draft":
        return cmd_draft(args, out, err)
    extra = [Path(p) for p in args.dict]
    model = Path(args.model)
    if model.suffix.lower() in (".toml", ".yaml", ".yml", ".csv") and model.is_file():
        for d in load_dictionaries(model):  # `dict show FILE`: every dictionary in it
            out.write(plain_lines(describe(d)) + "\n")
        return 0
    d = load_model(args.model, extra)
    out.write(plain_lines(describe(d)) + "\n")
    return 0


def cmd_draft(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    session, capture = open_session(Path(args.capture), read_options(args))
    session.ingest(capture.chunks())
    for w in capture.warnings:
        err.write(f"modscope: warning: {plain(w)}\n")
    seen = units_seen(session.store)
    if args.unit not in seen:
        units = ", ".join(str(u) for u in seen) or "none"
        raise UsageError(
            f"unit {args.unit} never answered in {args.capture} (units that did: {units})"
        )
    seen_unit = observe(session.store, args.unit)
    found = guesses(seen_unit)
    text = toml_of(seen_unit, found, args.capture, args.model)
    said = summary(seen_unit, found)
    if args.output in (None, "-"):
        out.write(text)
    else:
        target = Path(args.output)
        if target.exists() and not args.force:
            raise UsageError(f"{target} exists; give another -o FILE, or --force to overwrite it")
        target.write_text(text, encoding="utf-8")
        err.write(f"modscope: wrote {target}; check it with `modscope dict check {target}`\n")
    if not args.quiet:
        err.write("".join(f"{plain(line)}\n" for line in said))
    return 0


def register(sub: SubParsers) -> None:
    p = sub.add_parser("dict", help="device dictionaries: list, show, check, draft")
    dsub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    d = dsub.add_parser("list", help="the device models modscope ships")
    d.set_defaults(func=cmd_dict)
    d = dsub.add_parser("show", help="every entry a model's dictionary (or a file) has")
    d.add_argument("model", help="model name (see `modscope dict list`) or a dictionary file")
    d.add_argument(
        "--dict",
        action="append",
        default=[],
        metavar="FILE",
        help="your own file (TOML, YAML, CSV)",
    )
    d.set_defaults(func=cmd_dict)
    d = dsub.add_parser(
        "check", help="validate dictionary files (TOML, HA YAML, CSV): every problem, with its line"
    )
    d.add_argument("files", nargs="+", metavar="FILE")
    d.set_defaults(func=cmd_dict)
    d = dsub.add_parser(
        "draft",
        help="draft a dictionary for an unknown unit from a capture",
        description=(
            "Write a TOML dictionary for one unit from what the master read and wrote in a "
            "capture: every address range and an entry per register, string or 32-bit "
            "value. A type (u16, s16, u32, s32, f32, str, enum, bit field), word order or "
            "scale is proposed only where the values give evidence for it, and the "
            "evidence is written beside it (and listed on standard error); the rest is "
            "said to be unknown. Edit it, then bind it."
        ),
        epilog=DRAFT_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    d.add_argument("capture", metavar="CAPTURE", help="a capture file")
    d.add_argument("--unit", "-u", type=int, required=True, metavar="N", help="slave address")
    d.add_argument("-o", "--output", metavar="FILE", help="where to write it (default: stdout)")
    d.add_argument("--model", help="model name to give it (default: draft-unitN)")
    d.add_argument("--force", action="store_true", help="overwrite FILE if it exists")
    d.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        help="leave out the list of what was proposed and on what evidence",
    )
    add_line_options(d)
    d.set_defaults(func=cmd_dict)
