"""MkDocs hook: the command-line reference, rendered from the real parser at build time.

A page that contains the marker ``<!-- cli-reference -->`` gets, in its place, one section per
subcommand of :func:`surfsplat.cli.build_parser`: its usage line and a table per option group
(flags, value, default, description). Nothing is copied by hand, so the page follows the parser.
"""

from __future__ import annotations

import argparse
import html
import sys
from pathlib import Path

MARKER = "<!-- cli-reference -->"


def _cell(text: str) -> str:
    """Text for a Markdown table cell: HTML and Markdown specials escaped, no column breaks."""
    text = html.escape(" ".join(str(text).split()), quote=False)
    for ch in "\\`*_[]":
        text = text.replace(ch, "\\" + ch)
    return text.replace("|", "&#124;")


def _code(text: str) -> str:
    """Inline code in a table cell (a pipe inside code would still split the row)."""
    return "<code>" + html.escape(text, quote=False).replace("|", "&#124;") + "</code>"


def _help(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    """The action's help with argparse's %(default)s-style fields filled in."""
    if not action.help or action.help == argparse.SUPPRESS:
        return ""
    return parser._get_formatter()._expand_help(action)


def _value(action: argparse.Action) -> str:
    """What the option takes: its choices, its metavar, or nothing for a switch."""
    if action.nargs == 0 or not action.option_strings:
        return ""
    if action.choices is not None and not isinstance(action.choices, dict):
        return _code("|".join(str(c) for c in action.choices))
    metavar = action.metavar or (action.dest.upper() if action.option_strings else action.dest)
    if isinstance(metavar, tuple):
        metavar = " ".join(metavar)
    if isinstance(action.nargs, int) and action.nargs > 1 and " " not in metavar:
        metavar = " ".join([metavar] * action.nargs)
    elif action.nargs in ("+", "*"):
        metavar = f"{metavar} ..."
    return _code(str(metavar))


def _default(action: argparse.Action) -> str:
    default = action.default
    if action.nargs == 0 or default is None or default == argparse.SUPPRESS or action.required:
        return ""
    if isinstance(default, (list, tuple)):
        default = " ".join(str(v) for v in default)
    return _code(str(default))


def _group_table(parser: argparse.ArgumentParser, actions: list[argparse.Action]) -> list[str]:
    rows = ["| option | value | default | description |", "|---|---|---|---|"]
    for action in actions:
        if isinstance(action, argparse._HelpAction) or action.help == argparse.SUPPRESS:
            continue
        names = ", ".join(action.option_strings) if action.option_strings else action.dest
        required = " (required)" if action.required and action.option_strings else ""
        rows.append(f"| {_code(names)}{required} | {_value(action)} | {_default(action)} | "
                    f"{_cell(_help(parser, action))} |")
    return rows if len(rows) > 2 else []


def _command_section(name: str, parser: argparse.ArgumentParser, summary: str, level: int) -> list[str]:
    lines = [f"{'#' * level} `{name}`", ""]
    if summary:
        summary = summary[0].upper() + summary[1:]
        lines += [_cell(summary if summary.endswith(".") else summary + "."), ""]
    usage = parser.format_usage().strip()
    if usage.startswith("usage: "):
        usage = usage[len("usage: "):]
    usage = "\n".join(line if i == 0 else "    " + line.strip() for i, line in enumerate(usage.splitlines()))
    lines += ["```text", usage, "```", ""]
    for group in parser._action_groups:
        actions = [a for a in group._group_actions if not isinstance(a, argparse._SubParsersAction)]
        table = _group_table(parser, actions)
        if not table:
            continue
        title = group.title or "options"
        lines += [f"**{_cell(title[0].upper() + title[1:])}**", ""]
        if group.description:
            lines += [_cell(group.description), ""]
        lines += table + [""]
    return lines


def cli_reference_markdown(src: Path | None = None) -> str:
    """The reference of the ``surfsplat`` command and every subcommand, as Markdown.

    ``src``: the repository's source folder, put first on ``sys.path`` so that the parser documented is
    this checkout's, whatever copy of the package is installed.
    """
    if src is not None and str(src) not in sys.path:
        sys.path.insert(0, str(src))
    from surfsplat.cli import build_parser

    parser = build_parser()
    lines = _command_section("surfsplat", parser, parser.description or "", 2)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    summaries = {choice.dest: choice.help for choice in sub._choices_actions}
    for name, subparser in sub.choices.items():
        lines += _command_section(f"surfsplat {name}", subparser, summaries.get(name, ""), 2)
    return "\n".join(lines)


def on_page_markdown(markdown: str, page, config, files) -> str:
    """Replace the marker with the generated reference."""
    if MARKER not in markdown:
        return markdown
    src = Path(config.config_file_path).resolve().parent / "src"
    return markdown.replace(MARKER, cli_reference_markdown(src))
