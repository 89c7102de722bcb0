"""Blocks of the README and the docs that a command makes, between markers: ``<!-- <name>: made by <command> -->``
and ``<!-- <name>: end -->``. The command writes them (`with_block`); a test checks each is what it would write."""

from __future__ import annotations

from pathlib import Path

PROJECT = Path(__file__).resolve().parent.parent
README = PROJECT / "README.md"
DOCS = PROJECT / "docs"


def markers(name: str, command: str) -> tuple[str, str]:
    return f"<!-- {name}: made by {command} -->", f"<!-- {name}: end -->"


def with_block(text: str, name: str, command: str, content: str) -> str:
    """``text`` with its block ``name`` holding ``content`` (the markers must be there already)."""
    begin, end = markers(name, command)
    if begin not in text or end not in text:
        raise ValueError(f"no block {name!r} (its markers: {begin} ... {end})")
    head, rest = text.split(begin, 1)
    return f"{head}{begin}\n{content}\n{end}{rest.split(end, 1)[1]}"


def write_block(path: Path, name: str, command: str, content: str) -> None:
    path.write_text(with_block(path.read_text(), name, command, content))
