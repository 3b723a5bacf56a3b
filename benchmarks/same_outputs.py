"""Saves or compares what the listings and the export write, byte for byte: `replay
--format jsonl|text|csv` and `export -o x.pcapng` of the demo, of every capture in
tests/captures and of the given files, with `--jobs 1` and `--jobs 2`.

    python benchmarks/same_outputs.py save DIR [FILE...]
    python benchmarks/same_outputs.py check DIR [FILE...]

`check` names every output that differs from the one saved and exits 1 if any does."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MODSCOPE = [sys.executable, "-m", "sniffer.cli"]
SKIP = {".md", ".csv"}  # notes, and the doctor's expected verdicts


def captures() -> list[str]:
    found = sorted(
        str(p)
        for p in (ROOT / "tests" / "captures").rglob("*")
        if p.is_file() and p.suffix.lower() not in SKIP
    )
    return ["", *found]  # "" is the demo


def outputs(path: str, jobs: str) -> dict[str, str]:
    """A digest of each output of `path` (the demo when empty)."""
    files = [path] if path else []
    found: dict[str, str] = {}
    for fmt in ("jsonl", "text", "csv"):
        run = subprocess.run(
            [*MODSCOPE, "replay", *files, "--format", fmt, "--jobs", jobs],
            capture_output=True,
            cwd=ROOT,
        )
        found[fmt] = _digest(run.stdout + b"\0" + run.stderr + bytes([run.returncode]))
    if path:
        with tempfile.TemporaryDirectory() as folder:
            out = Path(folder) / "x.pcapng"
            run = subprocess.run(
                [*MODSCOPE, "export", path, "-o", str(out), "--jobs", jobs],
                capture_output=True,
                cwd=ROOT,
            )
            body = out.read_bytes() if out.exists() else b""
            stderr = run.stderr.replace(str(out).encode(), b"OUT")
            found["pcapng"] = _digest(body + b"\0" + stderr + bytes([run.returncode]))
    return found


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def main() -> int:
    mode, folder, *extra = sys.argv[1:]
    saved = Path(folder) / "outputs.json"
    now: dict[str, dict[str, str]] = {}
    for path in [*captures(), *extra]:
        for jobs in ("1", "2"):
            now[f"{path or 'demo'} --jobs {jobs}"] = outputs(path, jobs)
    if mode == "save":
        Path(folder).mkdir(parents=True, exist_ok=True)
        saved.write_text(json.dumps(now, indent=1, sort_keys=True))
        print(f"{len(now)} outputs saved in {saved}")
        return 0
    before = json.loads(saved.read_text())
    bad = [
        f"{name} {fmt}"
        for name, digests in now.items()
        for fmt, digest in digests.items()
        if before.get(name, {}).get(fmt) != digest
    ]
    for line in bad:
        print(f"differs: {line}")
    print(f"{len(now)} files compared, {len(bad)} outputs differ")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
