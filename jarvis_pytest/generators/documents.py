"""Generators of text documents: .docx (python-docx) and .odt (odfpy) with plain paragraphs, deterministic from
their arguments (fixed metadata dates; the same content for the same arguments), so a task's document carries its instance's values."""

from __future__ import annotations

import io

from jarvis_pytest.generators.packages import FIXED_DATE, deterministic_package
from jarvis_pytest.generators.registry import generator


def _paragraph_list(paragraphs: list[str]) -> list[str]:
    if not isinstance(paragraphs, list) or not all(isinstance(p, (str, int, float)) for p in paragraphs):
        raise TypeError("`paragraphs` must be a list of strings")
    return [str(p) for p in paragraphs]


@generator("docx_document")
def docx_document(paragraphs: list[str]) -> bytes:
    """A .docx whose body is `paragraphs`, each a plain paragraph in the Normal style."""
    import datetime

    import docx

    d = docx.Document()
    for text in _paragraph_list(paragraphs):
        d.add_paragraph(text)
    stamp = datetime.datetime.fromisoformat(FIXED_DATE)
    d.core_properties.created = d.core_properties.modified = stamp
    d.core_properties.author = "jarvis"
    buf = io.BytesIO()
    d.save(buf)
    return deterministic_package(buf.getvalue())


@generator("odt_document")
def odt_document(paragraphs: list[str]) -> bytes:
    """An .odt whose body is `paragraphs`, each a plain paragraph in the default style."""
    from odf.opendocument import OpenDocumentText
    from odf.text import P

    doc = OpenDocumentText()
    for text in _paragraph_list(paragraphs):
        doc.text.addElement(P(text=text))
    buf = io.BytesIO()
    doc.write(buf)
    return deterministic_package(buf.getvalue(), odf=True)
