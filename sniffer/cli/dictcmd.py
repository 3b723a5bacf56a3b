"""Provides `modscope dict`: list the shipped device models, show one, check files."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TextIO

from dissectors.dictionary import DictionaryError
from sniffer.cli.options import SubParsers
from sniffer.text import plain, plain_lines


def cmd_dict(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from dissectors.dictionary import (
        builtin_models,
        describe,
        import_csv,
        import_home_assistant,
        load_dictionary,
        load_model,
    )

    if args.action == "list":
        for name, path in sorted(builtin_models().items()):
            d = load_dictionary(path)
            out.write(f"{plain(name):<12} {plain(d.name)}  ({len(d.entries)} entries)\n")
        return 0
    if args.action == "check":
        bad = 0
        for file in args.files:
            shown = plain(file)
            try:
                if file.endswith((".yaml", ".yml")):
                    found = import_home_assistant(file)
                    out.write(f"{shown}: ok, {len(found)} device(s) from Home Assistant YAML\n")
                elif file.endswith(".csv"):
                    d = import_csv(file)
                    out.write(f"{shown}: ok, {len(d.entries)} entries from CSV\n")
                else:
                    d = load_dictionary(file)
                    out.write(f"{shown}: ok, model {plain(d.model)}, {len(d.entries)} entries\n")
            except DictionaryError as exc:
                err.write(plain_lines(str(exc)) + "\n")
                bad += 1
        return 1 if bad else 0
    d = load_model(args.model, [Path(p) for p in args.dict])
    out.write(plain_lines(describe(d)) + "\n")
    return 0


def register(sub: SubParsers) -> None:
    p = sub.add_parser("dict", help="device dictionaries: list, show, check")
    dsub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    d = dsub.add_parser("list", help="the device models modscope ships")
    d.set_defaults(func=cmd_dict)
    d = dsub.add_parser("show", help="every entry a model's dictionary has")
    d.add_argument("model", help="model name (see `modscope dict list`)")
    d.add_argument("--dict", action="append", default=[], metavar="FILE", help="your own file")
    d.set_defaults(func=cmd_dict)
    d = dsub.add_parser("check", help="validate dictionary files (TOML, HA YAML, CSV)")
    d.add_argument("files", nargs="+", metavar="FILE")
    d.set_defaults(func=cmd_dict)
