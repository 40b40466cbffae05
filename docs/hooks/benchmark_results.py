"""MkDocs hook: the tables of ``benchmarks/results/*.md``, each with its date, machine and command.

A page that contains the marker ``<!-- benchmark-results -->`` gets, in its place, one section per
results file (anchor: the file's stem, e.g. ``benchmarks.md#peers``). The date, machine and
command are read from the file (``Date:``, ``Machine:``, ``Command:`` / ``Made by`` lines, or a
``python benchmarks/...`` command quoted in its header); what a file does not state is shown as
"not recorded", with the script that writes the file where one names it.
"""

from __future__ import annotations

import re
from pathlib import Path

MARKER = "<!-- benchmark-results -->"
_DATE = re.compile(r"\b(20\d\d-\d\d-\d\d)\b")
_COMMAND = re.compile(r"`(python3? benchmarks/[^`]+)`")
_WORDS = {"lod": "LOD", "gpu": "GPU"}
_LINK = re.compile(r"\]\(([a-z0-9_]+)\.md\)")


def _repo_root(config) -> Path:
    return Path(config.config_file_path).resolve().parent


def _writer(stem: str, scripts: dict[str, str]) -> str | None:
    """The benchmark script that names this results file, if exactly one does."""
    for pattern in (rf"results/{re.escape(stem)}\.md\b", rf"[\"']{re.escape(stem)}\.md[\"']",
                    rf"[\"']{re.escape(stem)}[\"']"):
        found = [name for name, text in scripts.items() if re.search(pattern, text)]
        if len(found) == 1:
            return found[0]
    return None


def _section(path: Path, scripts: dict[str, str]) -> list[str]:
    stem = path.stem
    lines = path.read_text(encoding="utf-8").splitlines()
    title, date, machine, command = None, None, None, None
    body: list[str] = []
    for line in lines:
        stripped = line.strip()
        if title is None and stripped.startswith("# "):
            title = stripped[2:].strip()
            continue
        if date is None and stripped.startswith("Date:"):
            date = stripped[len("Date:"):].strip()
            continue
        if machine is None and stripped.startswith("Machine:"):
            machine = stripped[len("Machine:"):].strip()
            continue
        if command is None and stripped.startswith("Command:"):
            command = stripped[len("Command:"):].strip()
            continue
        if command is None and stripped.startswith("Made by "):
            command = stripped[len("Made by "):].strip()
            continue
        if stripped.startswith("#"):   # the file's own sections sit below this one
            line = "##" + stripped
        body.append(_LINK.sub(r"](#\1)", line))
    if date is None and machine and _DATE.search(machine):
        date = _DATE.search(machine).group(1)
    if command is None:
        quoted = _COMMAND.search("\n".join(lines))
        if quoted:
            command = f"`{quoted.group(1)}`"
    if command is None:
        writer = _writer(stem, scripts)
        command = (f"not recorded (the file is written by `python benchmarks/{writer}`)" if writer
                   else "not recorded")
    heading = title or " ".join(_WORDS.get(w, w) for w in stem.split("_"))
    heading = heading[0].upper() + heading[1:]
    out = [f"## {heading} {{#{stem}}}", "",
           f"- **File**: `benchmarks/results/{path.name}`",
           f"- **Date**: {date or 'not recorded'}",
           f"- **Machine**: {machine or 'not recorded'}",
           f"- **Command**: {command}", ""]
    # a table needs a blank line before it
    previous = ""
    for line in body:
        if line.lstrip().startswith("|") and previous.strip() and not previous.lstrip().startswith("|"):
            out.append("")
        out.append(line)
        previous = line
    out.append("")
    return out


def benchmark_results_markdown(root: Path) -> str:
    """Every results file under ``root/benchmarks/results`` as Markdown sections."""
    scripts = {p.name: p.read_text(encoding="utf-8") for p in sorted((root / "benchmarks").glob("*.py"))}
    sections = [_section(path, scripts) for path in sorted((root / "benchmarks" / "results").glob("*.md"))]
    headings = [section[0].rsplit(" {#", 1)[0] for section in sections]
    lines: list[str] = []
    for section, heading in zip(sections, headings):
        if headings.count(heading) > 1:   # several files of one benchmark: name each by its file
            stem = section[0].rsplit("{#", 1)[1].rstrip("}")
            section = [f"{heading} ({stem}) {{#{stem}}}"] + section[1:]
        lines += section
    return "\n".join(lines)


def on_page_markdown(markdown: str, page, config, files) -> str:
    """Replace the marker with the results sections."""
    if MARKER not in markdown:
        return markdown
    return markdown.replace(MARKER, benchmark_results_markdown(_repo_root(config)))
