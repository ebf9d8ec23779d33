"""Generators of files Android tasks start from: contacts as vCard files (what a phone's Contacts app imports and
exports)."""

from __future__ import annotations

from jarvis_pytest.generators.registry import generator


def _escape(value: str) -> str:
    """A vCard 3.0 text value (RFC 2426 §4: backslash, comma and semicolon escaped)."""
    return str(value).replace("\\", "\\\\").replace(",", "\\,").replace(";", "\\;").replace("\n", "\\n")


@generator("vcard_contacts")
def vcard_contacts(contacts: list, version: str = "3.0") -> bytes:
    """A vCard file of `contacts` — each `[name, phone]`, `[name, phone, email]` or a dict with `name`, `phone`,
    `email` — in vCard 3.0 (RFC 2426) or 2.1, CRLF line ends: `N` (family;given), `FN`, `TEL;TYPE=CELL` and
    `EMAIL;TYPE=INTERNET`, as Android's Contacts apps write and read them."""
    if version not in ("2.1", "3.0"):
        raise TypeError("`version` must be 2.1 or 3.0")
    if not isinstance(contacts, list) or not contacts:
        raise TypeError("`contacts` must be a non-empty list of [name, phone(, email)] or dicts")
    lines: list[str] = []
    for c in contacts:
        if isinstance(c, dict):
            name, phone, email = c.get("name"), c.get("phone"), c.get("email")
        elif isinstance(c, (list, tuple)) and 2 <= len(c) <= 3:
            name, phone, email = c[0], c[1], (c[2] if len(c) == 3 else None)
        else:
            raise TypeError(f"a contact must be [name, phone(, email)] or a dict, not {c!r}")
        if not name or not phone:
            raise TypeError(f"a contact needs a name and a phone number: {c!r}")
        given, _, family = str(name).rpartition(" ") if " " in str(name) else ("", "", str(name))
        if not given:
            given, family = family, ""
        esc = _escape if version == "3.0" else str
        lines += ["BEGIN:VCARD", f"VERSION:{version}", f"N:{esc(family)};{esc(given)};;;", f"FN:{esc(name)}",
                  (f"TEL;TYPE=CELL:{phone}" if version == "3.0" else f"TEL;CELL:{phone}")]
        if email:
            lines.append(f"EMAIL;TYPE=INTERNET:{email}" if version == "3.0" else f"EMAIL;HOME:{email}")
        lines.append("END:VCARD")
    return ("\r\n".join(lines) + "\r\n").encode("utf-8")
