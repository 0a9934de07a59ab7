"""Copy the tables of the latest benchmark runs into docs/benchmarks.md (the last step of ``make bench``).

    python benchmarks/write_docs.py [--doc docs/benchmarks.md] [--out benchmarks/out]

Each ``<out>/<name>.md`` (written by ``report.save`` in ``bench_<name>.py``) replaces whatever lies
between ``<!-- bench:<name> -->`` and ``<!-- /bench:<name> -->`` in the document; the prose around
the markers stays. Sections without a fresh file keep their previous tables. A file whose markers
are missing is an error, and the document is then left as it was. The document is replaced
atomically.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from mimetic.atomic import atomic_write

ROOT = Path(__file__).resolve().parents[1]


def markers(name: str) -> tuple[str, str]:
    """The opening and closing marker of section ``name``."""
    return f"<!-- bench:{name} -->", f"<!-- /bench:{name} -->"


def replace_section(document: str, name: str, body: str) -> str:
    """``document`` with the text between section ``name``'s markers replaced by ``body``.

    Raises ``ValueError`` when the markers are missing, repeated or out of order.
    """
    start, end = markers(name)
    if document.count(start) != 1 or document.count(end) != 1 or document.index(start) > document.index(end):
        raise ValueError(
            f"section {name!r}: expected one {start!r} followed by one {end!r} "
            f"(found {document.count(start)} and {document.count(end)}); put them around the section's "
            "tables in the document"
        )
    head, rest = document.split(start)
    _, tail = rest.split(end)
    return f"{head}{start}\n{body.strip()}\n{end}{tail}"


def write_docs(doc: Path, out: Path) -> list[str]:
    """Replace every section of ``doc`` that has a file in ``out``; return the sections' names."""
    fresh = {path.stem: path.read_text(encoding="utf-8") for path in sorted(out.glob("*.md"))}
    text = doc.read_text(encoding="utf-8")
    for name, body in fresh.items():
        text = replace_section(text, name, body)
    with atomic_write(doc, "w") as handle:
        handle.write(text)
    return list(fresh)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--doc", type=Path, default=ROOT / "docs" / "benchmarks.md")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "out")
    args = parser.parse_args()
    names = write_docs(args.doc, args.out)
    print(f"{args.doc}: {', '.join(names) or 'no section'} rewritten from {args.out}")


if __name__ == "__main__":
    main()
