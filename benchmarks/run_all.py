"""Run every benchmark and write its tables into docs/performance.md (between the markers
``<!-- bench:NAME -->`` and ``<!-- /bench:NAME -->``), with the machine, date and versions.

    python benchmarks/run_all.py [--quick] [--no-docs] [--only NAME,...] [--out results.txt]

--quick: smaller sizes, fewer rounds and shorter limits (a few minutes instead of about
half an hour). A peer that is not installed shows as "not installed"; a benchmark that
fails shows its error in its section, and the others still run. Optional benchmarks of
other parts (benchmarks/loop.py: the compiled integration loop; benchmarks/sweep.py: the
sweeps) are run when present.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from harness import ROOT, compiler, git_commit, load, machine, replace_between_markers, today, versions  # noqa: E402

DOCS = ROOT / "docs" / "performance.md"


def steps(quick: bool) -> list[tuple[str, list[str], float]]:
    """(section, script and arguments, time limit [s]) of every benchmark."""
    return [
        (
            "evaluation",
            ["evaluation.py"]
            + (["--sizes", "4,10,20", "--setup-limit", "30", "--rounds", "7"] if quick else ["--sizes", "4,10,20,40"]),
            3600,
        ),
        ("chain", ["chain_simulation.py"] + (["--rounds", "1"] if quick else ["--rounds", "3"]), 1800),
        (
            "derivation",
            ["derivation.py"]
            + (["--sizes", "2,4,6,8,10", "--limit", "20"] if quick else ["--limit", "60", "--file-sizes", "50"]),
            3600,
        ),
        ("car", ["car_simulation.py"], 900),
        ("loop", ["loop.py"] + (["--repeats", "3"] if quick else []), 1800),
        ("sweep", ["sweep.py"] + (["--repeats", "1"] if quick else []), 3600),
        ("scaling", ["scaling.py"] + (["--sizes", "2,5,10"] if quick else []), 1800),
        ("linearise", ["linearise.py", "--speeds", "101" if quick else "1001"], 900),
        ("linearise_peers", ["linearise_peers.py", "--spins", "101" if quick else "1001"], 600),
        ("iftomm", ["iftomm.py"] + (["--quick"] if quick else []), 900),
        ("robots", ["robots.py"] + (["--robot", "panda", "--robot", "solo12"] if quick else ["--runs", "3"]), 1800),
        ("viewer", ["viewer.py"] + (["--quick"] if quick else []), 900),
        ("gear_train", ["gear_train.py"], 600),
    ]


def accepts(script: Path, option: str) -> bool:
    proc = subprocess.run([sys.executable, str(script), "--help"], capture_output=True, text=True)
    return option in proc.stdout


def run_step(name: str, argv: list[str], limit: float, quick: bool) -> tuple[str, str]:
    """Run one benchmark; returns (what it printed, its Markdown section)."""
    script = HERE / argv[0]
    if not script.exists():
        return "", f"*Not run: `benchmarks/{argv[0]}` is not in this checkout.*"
    args = list(argv[1:])
    if "--quick" in args and not accepts(script, "--quick"):
        args.remove("--quick")
    if "--repeats" in args and not accepts(script, "--repeats"):
        args = args[: args.index("--repeats")] + args[args.index("--repeats") + 2 :]
    command = "python " + " ".join([f"benchmarks/{argv[0]}", *args])
    md = Path(tempfile.mkdtemp(prefix="appell_md_")) / f"{name}.md"
    if accepts(script, "--markdown"):
        args += ["--markdown", str(md)]
    cmd = [sys.executable, str(script), *args]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=limit)
    except subprocess.TimeoutExpired as exc:
        out = (exc.stdout or b"").decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        return out, f"*`{command}` did not finish within {limit:g} s.*\n\n```text\n{out.strip()}\n```"
    wall = time.perf_counter() - t0
    printed = proc.stdout + (proc.stderr[-3000:] if proc.returncode else "")
    if proc.returncode:
        tail = proc.stderr.strip().splitlines()[-1:] or ["no message"]
        body = f"*`{command}` failed (exit code {proc.returncode}): {tail[0][:300]}*"
        if proc.stdout.strip():
            body += f"\n\n```text\n{proc.stdout.strip()}\n```"
        return printed, body
    if md.exists():
        body = md.read_text().strip()
    else:
        body = f"```text\n{proc.stdout.strip(chr(10)).rstrip()}\n```"
    return printed, body + f"\n\n<small>`{command}` ({wall:.0f} s)</small>"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--no-docs", action="store_true", help="print only; leave docs/performance.md alone")
    ap.add_argument(
        "--only",
        help="comma-separated sections (evaluation, chain, derivation, car, loop, sweep, "
        "scaling, linearise, linearise_peers, iftomm, robots, viewer)",
    )
    ap.add_argument("--out", help="also write everything printed to this file")
    args = ap.parse_args()
    chosen = set(args.only.split(",")) if args.only else None
    head = [
        f"- machine: {machine()}; {compiler()}",
        f"- date: {today()}; {load()} at the start",
        f"- versions: {versions()}; appell at commit {git_commit()}",
        f"- command: `python benchmarks/run_all.py{' --quick' if args.quick else ''}"
        f"{' --only ' + args.only if args.only else ''}`"
        + (" (quick: smaller sizes, fewer rounds)" if args.quick else ""),
    ]
    print("\n".join(head), flush=True)
    printed = ["\n".join(head)]

    def write(sections: dict[str, str]):
        """Write the sections done so far (the docs stay useful if a later step is cut off)."""
        if args.no_docs:
            return
        text = DOCS.read_text()
        for name, body in sections.items():
            try:
                text = replace_between_markers(text, name, body)
            except KeyError as exc:
                print(f"warning: {exc} in {DOCS}; section {name!r} not written", file=sys.stderr)
        DOCS.write_text(text)

    if args.only and not args.no_docs:
        # a partial re-run keeps the machine section of the full run and adds a line to it
        text = DOCS.read_text()
        begin, end = "<!-- bench:machine -->", "<!-- /bench:machine -->"
        earlier = text[text.find(begin) + len(begin) : text.find(end)].strip()
        head = [
            earlier,
            f"- re-run of {args.only}: {today()}, {load()} at the start; {versions()}; appell at commit {git_commit()}",
        ]
    write({"machine": "\n".join(head + ["- (running)"])})
    for name, argv, limit in steps(args.quick):
        if chosen and name not in chosen:
            continue
        print(f"\n== {name}: benchmarks/{' '.join(argv)}", flush=True)
        out, body = run_step(name, argv, limit, args.quick)
        print(out, end="", flush=True)
        printed += [f"\n== {name}", out]
        write({name: body})
        if args.out:
            Path(args.out).write_text("\n".join(printed))
    head.append(f"- {'re-run ' if args.only else ''}finished: {today()}; {load()} at the end")
    write({"machine": "\n".join(head)})
    if args.out:
        Path(args.out).write_text("\n".join(printed))
    if not args.no_docs:
        print(f"\nwrote {DOCS}")


if __name__ == "__main__":
    main()
