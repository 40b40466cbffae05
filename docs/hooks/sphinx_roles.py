"""MkDocs hook: Sphinx cross-reference roles in rendered docstrings shown as plain code.

The package's docstrings use Sphinx roles (``:class:`~surfsplat.camera.Camera```); the API reference
renders them with mkdocstrings, which leaves the role's name in front of the code span
(``:class:<code>~surfsplat.camera.Camera</code>``). This hook drops the role and, as Sphinx does for
a leading ``~``, keeps only the last component of the dotted name.
"""

from __future__ import annotations

import re

_ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|data|attr|exc|obj|const):(<code>)(~?)([^<]*)(</code>)")


def _plain(match: re.Match) -> str:
    name = match.group(3)
    if match.group(2):
        name = name.split(".")[-1]
    return f"{match.group(1)}{name}{match.group(4)}"


def on_page_content(html: str, page, config, files) -> str:
    """Rewrite the roles in the pages that render docstrings."""
    if ":<code>" not in html:
        return html
    return _ROLE.sub(_plain, html)
