"""A Griffe extension for the site's API reference (``extensions:`` of mkdocstrings in
``mkdocs.yml``): the project's docstrings are Google style with Sphinx roles
(``:class:`~moma_env.sim.Frame```) and double-backtick literals, which Markdown would show
verbatim; this turns them into code spans (:func:`training.docs_pages.rst_to_markdown`),
and fences RST simple tables as text blocks (:func:`training.docs_pages.rst_tables_as_text`),
before mkdocstrings renders them. Needs the ``docs`` extra (griffe)."""

from __future__ import annotations

from typing import Any

import griffe

from training.docs_pages import rst_tables_as_text, rst_to_markdown

__all__ = ["SphinxRoles"]


class SphinxRoles(griffe.Extension):
    """Rewrite every loaded object's docstring with :func:`rst_tables_as_text` and :func:`rst_to_markdown`."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        """Griffe event: an object was loaded (module, class, function, attribute)."""
        if obj.docstring is not None:
            obj.docstring.value = rst_to_markdown(rst_tables_as_text(obj.docstring.value))
