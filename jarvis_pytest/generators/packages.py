"""Office packages (.docx, .xlsx, .pptx, .odt, .ods) made deterministic to the byte: the libraries that write them
stamp the time of writing into zip members and metadata, and odfpy declares namespaces by process history."""

from __future__ import annotations

import io

FIXED_DATE = "2025-01-06T09:00:00"  # every generated document's created/modified date


def _canonical_namespaces(body: bytes) -> bytes:
    """The XML `body` with its root element declaring every namespace odfpy knows, sorted by prefix. odfpy
    declares on each root the namespaces its process has met so far (a class-level dict shared by all
    documents), so the same document would otherwise come out differently after another was built."""
    import re

    from odf.namespaces import nsdict

    m = re.search(rb"<[A-Za-z][^>]*>", body)
    if m is None:
        return body
    tag = m.group(0)
    decls = dict(re.findall(rb'\sxmlns:([\w.-]+)="([^"]*)"', tag))
    for uri, prefix in nsdict.items():
        decls.setdefault(prefix.encode(), uri.encode())
    bare = re.sub(rb'\sxmlns:[\w.-]+="[^"]*"', b"", tag)
    end = re.match(rb"<[\w:.-]+", bare).end()
    root = bare[:end] + b"".join(b' xmlns:%s="%s"' % (k, decls[k]) for k in sorted(decls)) + bare[end:]
    return body[:m.start()] + root + body[m.end():]


def deterministic_package(data: bytes, odf: bool = False) -> bytes:
    """The same package with every member's time fixed (and, for ODF, the volatile meta dates dropped and the
    namespace declarations made canonical; for Office Open XML, the created and modified dates set to
    FIXED_DATE: openpyxl stamps `modified` with the time of saving), so equal arguments give equal bytes."""
    import datetime
    import re
    import zipfile

    when = datetime.datetime.fromisoformat(FIXED_DATE).timetuple()[:6]
    src = zipfile.ZipFile(io.BytesIO(data))
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as dst:
        for info in src.infolist():
            body = src.read(info.filename)
            if info.filename == "meta.xml":
                body = re.sub(rb"<meta:(creation-date|generator)>[^<]*</meta:\1>", b"", body)
            if info.filename == "docProps/core.xml":
                body = re.sub(rb"(<dcterms:(created|modified)\b[^>]*>)[^<]*(</dcterms:\2>)",
                              rb"\g<1>" + FIXED_DATE.encode() + rb"Z\g<3>", body)
            if odf and info.filename.endswith(".xml"):
                body = _canonical_namespaces(body)
            fixed = zipfile.ZipInfo(info.filename, date_time=when)
            fixed.compress_type = zipfile.ZIP_STORED if info.filename == "mimetype" else zipfile.ZIP_DEFLATED
            dst.writestr(fixed, body)
    return out.getvalue()
