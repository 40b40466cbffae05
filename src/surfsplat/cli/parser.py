"""The argument parser class of the ``surfsplat`` command: short usage errors with suggestions.

A usage error prints three lines (four with a suggestion of its own) instead of the full usage::

    usage: surfsplat render INPUT... -o OUTPUT [options]
    surfsplat render: error: argument --technique: invalid choice: 'ewq'; did you mean 'ewa'? (choose from ...)
    see `surfsplat render --help`

A misspelled option, choice or subcommand gets the closest known one (:func:`difflib.get_close_matches`),
as ``suggest_on_error`` does on Python 3.14's argparse; the exit status stays 2.
"""

from __future__ import annotations

import argparse
import difflib

#: How similar a word must be to be suggested (:func:`difflib.get_close_matches`' cutoff).
SUGGEST_CUTOFF = 0.6


def closest(word: str, candidates) -> str | None:
    """The candidate closest to ``word`` (:data:`SUGGEST_CUTOFF` or more similar), or None."""
    matches = difflib.get_close_matches(str(word), [str(c) for c in candidates], n=1, cutoff=SUGGEST_CUTOFF)
    return matches[0] if matches else None


def _is_option(text: str) -> bool:
    """Whether a command-line word looks like an option (``-x``, ``--name``), not a negative number."""
    if not text.startswith("-") or text in ("-", "--"):
        return False
    try:
        float(text)
    except ValueError:
        return True
    return False


class Parser(argparse.ArgumentParser):
    """ArgumentParser whose usage errors are short (:meth:`short_usage`, the error, a pointer to
    ``--help``) and suggest the closest option, choice or subcommand to a misspelled one."""

    def short_usage(self) -> str:
        """One line: ``usage: PROG POSITIONALS... REQUIRED-OPTIONS [options]``."""
        parts = [self.prog]
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                parts.append("COMMAND")
            elif not action.option_strings:
                name = action.metavar if isinstance(action.metavar, str) else action.dest.upper()
                parts.append({"+": f"{name}...", "*": f"[{name}...]", "?": f"[{name}]"}.get(str(action.nargs), name))
        for action in self._actions:
            if action.option_strings and action.required:
                flag = min(action.option_strings, key=len)
                name = action.metavar if isinstance(action.metavar, str) else action.dest.upper()
                parts.append(f"{flag} {name}")
        return "usage: " + " ".join(parts + ["[options]"])

    def error(self, message: str):
        """Print the short usage, ``PROG: error: MESSAGE`` and where the full help is; exit with status 2."""
        self.exit(2, f"{self.short_usage()}\n{self.prog}: error: {message}\nsee `{self.prog} --help`\n")

    def parse_args(self, args=None, namespace=None):
        """As argparse's, but words no option takes are reported by the subcommand they were given to,
        with the closest known option to each unknown one."""
        namespace, extras = self.parse_known_args(args, namespace)
        if extras:
            parser = self._subcommand_parser(namespace) or self
            parser.error(parser.unrecognized(extras))
        return namespace

    def _subcommand_parser(self, namespace) -> Parser | None:
        """The parser of the subcommand ``namespace`` holds, if any."""
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                chosen = action.choices.get(getattr(namespace, action.dest, None) or "")
                return chosen if isinstance(chosen, Parser) else None
        return None

    def unrecognized(self, extras: list[str]) -> str:
        """The error message of the words ``extras`` no option took, with suggestions for options."""
        known = [s for action in self._actions for s in action.option_strings]
        options = [word.split("=", 1)[0] for word in extras if _is_option(word)]
        hints = []
        for name in options:
            match = closest(name, [s for s in known if s.startswith("--") == name.startswith("--")])
            if match:
                hints.append(f"did you mean {match}?" if len(options) == 1 else f"{name}: did you mean {match}?")
        return f"unrecognized arguments: {' '.join(extras)}" + ("; " + "; ".join(hints) if hints else "")

    def _check_value(self, action, value):
        # argparse's check of ``choices``, with the closest choice suggested (a private hook of
        # argparse on 3.10 to 3.13; without it the plain message of argparse remains)
        if action.choices is None or value in action.choices:
            return
        choices = list(action.choices)
        match = closest(value, choices)
        hint = f"; did you mean {match!r}?" if match is not None else ""
        listed = ", ".join(str(c) for c in choices)
        if isinstance(action, argparse._SubParsersAction):
            raise argparse.ArgumentError(None, f"unknown command {value!r}{hint} (commands: {listed})")
        raise argparse.ArgumentError(action, f"invalid choice: {value!r}{hint} (choose from {listed})")

