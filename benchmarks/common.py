"""Shared helpers of the benchmark scripts: machine description and table output."""

from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

RESULTS = Path(__file__).parent / "results"


def cpu_name() -> str:
    """The CPU model name from /proc/cpuinfo (Linux) or platform.processor()."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_description(gl_renderer: str | None = None) -> str:
    """One line naming the machine: CPU, usable cores and, if given, the GL renderer."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    text = f"{cpu_name()}, {cores} cores, Python {platform.python_version()}"
    if gl_renderer:
        text += f", GL: {gl_renderer}"
    return text


def fmt(value) -> str:
    """A table cell: floats to 3 significant digits (thousands separated), ints with separators."""
    if isinstance(value, float):
        return f"{value:,.3g}" if abs(value) < 1000 else f"{value:,.0f}"
    if isinstance(value, int):
        return f"{value:,}"
    return str(value)


def markdown_table(columns: list[str], rows: list[list]) -> list[str]:
    """The lines of a Markdown table."""
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    return lines + ["| " + " | ".join(fmt(v) for v in row) + " |" for row in rows]


def save_results(name: str, text: str, data) -> None:
    """Print ``text`` and save it as ``results/{name}.md`` beside ``data`` as ``results/{name}.json``."""
    print(text)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{name}.md").write_text(text)
    (RESULTS / f"{name}.json").write_text(json.dumps(data, indent=1))


def write_table(name: str, columns: list[str], rows: list[list], machine: str) -> str:
    """Print a Markdown table and save it (and a JSON copy) under benchmarks/results/.

    Returns the Markdown text. Files: ``results/{name}.md`` and ``results/{name}.json``.
    """
    lines = [f"Machine: {machine}", f"Date: {time.strftime('%Y-%m-%d')}", ""] + markdown_table(columns, rows)
    text = "\n".join(lines)
    print(text)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{name}.md").write_text(text + "\n")
    (RESULTS / f"{name}.json").write_text(json.dumps(
        {"machine": machine, "date": time.strftime("%Y-%m-%d"), "columns": columns, "rows": rows}, indent=1))
    return text


def label(image: np.ndarray, text: str) -> np.ndarray:
    """The image with ``text`` written at its top left (black on a white box)."""
    picture = Image.fromarray(image)
    draw = ImageDraw.Draw(picture)
    box = draw.textbbox((4, 3), text)
    draw.rectangle((box[0] - 2, box[1] - 2, box[2] + 2, box[3] + 2), fill=(255, 255, 255))
    draw.text((4, 3), text, fill=(0, 0, 0))
    return np.asarray(picture)
