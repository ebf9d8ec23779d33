"""Checks of an Android device's state, read through adb the way the platform stores it.

Every check reads the store the app itself writes, with the platform's own tools run in the device's `sh`:

- system settings: `settings get <system|secure|global> <key>` (keys of `android.provider.Settings`), with the
  value's type checked (a brightness is an integer, a font scale a number), and, where a service holds the real
  state, the service itself (`cmd uimode night` for Dark theme, `dumpsys bluetooth_manager` for Bluetooth);
- contacts, calendar events and the call log: their content providers (`content query --uri content://...`, the
  documented `ContactsContract`, `CalendarContract` and `CallLog.Calls` URIs and columns), parsed by
  `devices/android/outputs.py:parse_content_rows`;
- text messages: the telephony provider's database `mmssms.db` (`Telephony.Sms` columns), read with root, because
  the `content://sms` view that a non-default app gets hides drafts (AOSP `SmsProvider`/`ProviderUtil
  .isAccessRestricted`);
- alarms: AlarmManager's next alarm clock (`AlarmManager.getNextAlarmClock`, as `dumpsys alarm` prints it), which
  every clock app sets for its next alarm;
- Chrome's bookmarks: the `Bookmarks` JSON of its profile (`app_chrome/Default/Bookmarks`), read with root and
  judged like Chromium's on the desktop (`browser.check_bookmark`: its checksum proves Chrome wrote it);
- files: their bytes, pulled with `adb pull` (`FinalState.pull`), and vCard files parsed as vCards.

Expected values come from the task's inputs (known on the host), never from what the agent left; what the
instruction did not ask to change (the other contacts, messages, calls, events, settings, files) is checked
unchanged against what the set-up made. Every reason names what was expected and what was found.
"""

from __future__ import annotations

import io
import quopri
import re
import shlex
import time
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from jarvis_pytest.devices.android.outputs import parse_content_rows, settings_value
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.evaluators.browser import check_bookmark
from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState, judge_file

q = shlex.quote


def _short(text: Any, limit: int = 120) -> str:
    text = str(text)
    return repr(text if len(text) <= limit else text[:limit] + "…")


def _run(state: FinalState, command: str, *, root: bool = False, platform: str | None = None) -> str:
    """`command`'s standard output on the device (as root when `root`); a failing command is an infrastructure
    error naming it (the store could not be read: no finding about the agent's work)."""
    res = state.run(command, platform, user="root" if root else None)
    if res.returncode != 0:
        raise InfrastructureError(f"android: `{command[:160]}` failed ({res.returncode}): "
                                  f"{(res.stdout + res.stderr).strip()[:300]}")
    return res.stdout


def content_rows(state: FinalState, uri: str, projection: list[str], where: str | None = None, *,
                 root: bool = False, platform: str | None = None) -> list[dict[str, str | None]]:
    """Rows of `content query --uri URI --projection a:b:c [--where W]` as dicts."""
    cmd = f"content query --uri {q(uri)} --projection {q(':'.join(projection))}"
    if where:
        cmd += f" --where {q(where)}"
    out = _run(state, cmd, root=root, platform=platform)
    if "Error while accessing provider" in out or out.lstrip().startswith(("Exception", "java.lang.")):
        raise InfrastructureError(f"android: content query {uri} failed: {out.strip()[:300]}")
    return parse_content_rows(out, projection)


# -- settings --------------------------------------------------------------------------------------------------
NAMESPACES = ("system", "secure", "global")


def setting(state: FinalState, namespace: str, key: str, platform: str | None = None) -> str | None:
    """`settings get namespace key` (None when unset)."""
    if namespace not in NAMESPACES:
        raise ValueError(f"settings namespace must be one of {NAMESPACES}, not {namespace!r}")
    return settings_value(_run(state, f"settings get {namespace} {q(key)}", platform=platform))


def typed(raw: str | None, kind: str) -> int | float | str | None:
    """`raw` as the kind a setting holds (int, float or text); None when unset or not of that kind."""
    if raw is None or not raw.strip():
        return None
    text = raw.strip()
    try:
        if kind == "int":
            return int(text) if re.fullmatch(r"-?\d+", text) else None
        if kind == "float":
            return float(text) if re.fullmatch(r"-?\d+(\.\d+)?", text) else None
    except ValueError:
        return None
    return text


def check_setting(raw: str | None, namespace: str, key: str, expected: Any, kind: str = "int",
                  tolerance: float = 0.0) -> tuple[bool, str]:
    """Whether the stored `raw` text of a setting is `expected` as a `kind` (within `tolerance` for numbers), and
    the finding as text."""
    want = typed(str(expected), kind) if expected is not None else None
    got = typed(raw, kind)
    if expected is None:  # unset: no value, or the empty string that a reset writes (e.g. `wm density reset`)
        unset = raw is None or not raw.strip()
        return unset, f"{namespace} {key} unset" if unset else f"{namespace} {key} = {raw!r}"
    if got is None:
        return False, (f"{namespace} {key} unset" if raw is None else
                       f"{namespace} {key} = {raw!r}, which is not a{'n integer' if kind == 'int' else ' number'}"
                       if kind in ("int", "float") else f"{namespace} {key} = {raw!r}")
    ok = abs(got - want) <= tolerance if kind in ("int", "float") else got == want  # type: ignore[operator]
    return ok, f"{namespace} {key} = {raw.strip()!r}" if raw is not None else f"{namespace} {key} unset"


def _unchanged(state: FinalState, unchanged: list | None, platform: str | None) -> list[str]:
    """What differs among `unchanged` ([namespace, key, value-or-null, kind?] each, the values the set-up made)."""
    problems = []
    for item in unchanged or []:
        namespace, key, value = item[0], item[1], item[2]
        kind = item[3] if len(item) > 3 else ("text" if value is None else "int")
        ok, found = check_setting(setting(state, namespace, key, platform), namespace, key, value, kind)
        if not ok:
            problems.append(f"{found} (set up as {value!r}: changed)" if value is not None else
                            f"{found} (unset at set-up: changed)")
    return problems


@evaluator("android_setting_is")
def android_setting_is(state: FinalState, namespace: str, key: str, expected: Any, kind: str = "int",
                       tolerance: float = 0.0, values: dict[str, Any] | None = None, unchanged: list | None = None,
                       platform: str | None = None) -> Verdict:
    """`settings get namespace key` is `expected` as a `kind` (int, float or text; numbers within `tolerance`).
    `values` maps the instruction's words to the stored value (`{"maximum": 255}`); `unchanged` lists
    `[namespace, key, value, kind]` settings the set-up made that must still hold (null: unset)."""
    stored = values.get(str(expected), expected) if values else expected
    tol = f" (±{tolerance:g})" if tolerance else ""
    want = f"{namespace} {key} = {stored}{tol}" + (f" ({expected})" if values else "")
    ok, found = check_setting(setting(state, namespace, key, platform), namespace, key, stored, kind, tolerance)
    if not ok:
        return Verdict.check(False, want, found)
    damage = _unchanged(state, unchanged, platform)
    if unchanged:
        want += " and " + ", ".join(f"{u[0]} {u[1]} left as set up" for u in unchanged)
    return Verdict.check(not damage, want, "; ".join(damage) or found)


NIGHT_RE = re.compile(r"Night mode:\s*(\w+)")
UI_NIGHT_MODE = {"0": "auto", "1": "no", "2": "yes", "3": "custom"}  # UiModeManager.MODE_NIGHT_*


def parse_night_mode(text: str) -> str | None:
    """`cmd uimode night` → yes | no | auto | custom (UiModeManagerService's shell prints `Night mode: <mode>`)."""
    m = NIGHT_RE.search(text)
    return m.group(1).lower() if m else None


@evaluator("android_dark_theme")
def android_dark_theme(state: FinalState, on: bool = True, unchanged: list | None = None,
                       platform: str | None = None) -> Verdict:
    """Dark theme is on (off): the UI mode service reports night mode `yes` (`no`) — not `auto` or a custom
    schedule — and the persisted `secure ui_night_mode` agrees (2 = yes, 1 = no, `UiModeManager.MODE_NIGHT_*`).
    `unchanged` as for `android_setting_is`."""
    want_mode = "yes" if on else "no"
    want = f"Dark theme {'on' if on else 'off'} (UI mode service: night mode {want_mode}; secure ui_night_mode " \
           f"{'2' if on else '1'})"
    service = parse_night_mode(_run(state, "cmd uimode night", platform=platform))
    stored = setting(state, "secure", "ui_night_mode", platform)
    found = f"night mode {service or 'unreported'}, ui_night_mode {stored!r}"
    if service != want_mode or UI_NIGHT_MODE.get((stored or "").strip()) != want_mode:
        return Verdict.check(False, want, found)
    damage = _unchanged(state, unchanged, platform)
    return Verdict.check(not damage, want, "; ".join(damage) or found)


BT_ENABLED_RE = re.compile(r"^\s*enabled:\s*(true|false)", re.M)


def parse_bluetooth_enabled(text: str) -> bool | None:
    """`dumpsys bluetooth_manager` → whether the adapter is enabled (BluetoothManagerService prints
    `Bluetooth Status` / `  enabled: true|false` / `  state: ...`)."""
    m = BT_ENABLED_RE.search(text)
    return None if m is None else m.group(1) == "true"


@evaluator("android_bluetooth")
def android_bluetooth(state: FinalState, on: bool = True, unchanged: list | None = None,
                      platform: str | None = None) -> Verdict:
    """Bluetooth is on (off): the Bluetooth manager service reports the adapter enabled (disabled) and the
    persisted `global bluetooth_on` agrees (1 on, 0 off); the flag alone (written without the adapter) does not
    count. `unchanged` as for `android_setting_is`."""
    want = f"Bluetooth {'on' if on else 'off'} (the adapter {'enabled' if on else 'disabled'}, global bluetooth_on " \
           f"{1 if on else 0})"
    enabled = parse_bluetooth_enabled(_run(state, "dumpsys bluetooth_manager", platform=platform))
    flag = setting(state, "global", "bluetooth_on", platform)
    found = f"adapter {'enabled' if enabled else 'disabled' if enabled is False else 'state unreported'}, " \
            f"bluetooth_on {flag!r}"
    flag_on = (flag or "").strip() not in ("", "0")
    if enabled is not on or flag_on is not on:
        return Verdict.check(False, want, found)
    damage = _unchanged(state, unchanged, platform)
    return Verdict.check(not damage, want, "; ".join(damage) or found)


# -- people: contacts, vCards, phone numbers --------------------------------------------------------------------
def phone_digits(number: Any) -> str:
    """A phone number as its digits, without the North American country code 1 (`+1 555-234-1234`, `(555)
    234-1234` and `5552341234` are one number)."""
    digits = re.sub(r"\D", "", str(number))
    return digits[1:] if len(digits) == 11 and digits.startswith("1") else digits


def name_key(name: Any) -> str:
    return " ".join(str(name).split()).casefold()


@dataclass
class Person:
    """A contact as stored: its name, phone numbers and e-mail addresses."""

    name: str
    phones: list[str] = field(default_factory=list)
    emails: list[str] = field(default_factory=list)

    def describe(self) -> str:
        return f"{self.name!r} (phones {self.phones or 'none'}, e-mails {self.emails or 'none'})"


CONTACTS_RAW = "content://com.android.contacts/raw_contacts"
CONTACTS_DATA = "content://com.android.contacts/data"
MIME_NAME = "vnd.android.cursor.item/name"
MIME_PHONE = "vnd.android.cursor.item/phone_v2"
MIME_EMAIL = "vnd.android.cursor.item/email_v2"


def people_from_rows(raw: list[dict], data: list[dict]) -> list[Person]:
    """Contacts from `ContactsContract.RawContacts` rows (`_id`, `display_name`, `deleted`) and `Data` rows
    (`raw_contact_id`, `mimetype`, `data1`): one per raw contact not marked deleted, named by its structured name
    (else its display name)."""
    alive = {r["_id"]: r for r in raw if r.get("_id") and (r.get("deleted") or "0") == "0"}
    people = {rid: Person(name=(r.get("display_name") or "").strip()) for rid, r in alive.items()}
    for row in data:
        person = people.get(row.get("raw_contact_id") or "")
        value = (row.get("data1") or "").strip()
        if person is None or not value:
            continue
        mime = row.get("mimetype")
        if mime == MIME_NAME:
            person.name = value
        elif mime == MIME_PHONE:
            person.phones.append(value)
        elif mime == MIME_EMAIL:
            person.emails.append(value)
    return [people[k] for k in sorted(people, key=lambda k: int(k) if k.isdigit() else 0)]


def read_contacts(state: FinalState, platform: str | None = None) -> list[Person]:
    raw = content_rows(state, CONTACTS_RAW, ["_id", "display_name", "deleted"], platform=platform)
    data = content_rows(state, CONTACTS_DATA, ["raw_contact_id", "mimetype", "data1"], platform=platform)
    return people_from_rows(raw, data)


def _expected_people(contacts: list[dict]) -> list[Person]:
    out = []
    for c in contacts:
        phones = c.get("phones", [c["phone"]] if c.get("phone") else [])
        emails = c.get("emails", [c["email"]] if c.get("email") else [])
        out.append(Person(str(c["name"]), [str(p) for p in phones], [str(e) for e in emails]))
    return out


def compare_people(found: list[Person], expected: list[Person], what: str = "the contacts") -> Verdict:
    """`found` holds exactly the `expected` people: each name once (no duplicate), with exactly its phone numbers
    (compared as digits) and e-mail addresses (case aside), and nobody else."""
    want = f"{what} exactly: " + "; ".join(p.describe() for p in expected)
    problems = []
    by_name: dict[str, list[Person]] = {}
    for p in found:
        by_name.setdefault(name_key(p.name), []).append(p)
    for e in expected:
        hits = by_name.get(name_key(e.name), [])
        if not hits:
            problems.append(f"no contact named {e.name!r}")
            continue
        if len(hits) > 1:
            problems.append(f"{len(hits)} contacts named {e.name!r} (a duplicate)")
            continue
        got = hits[0]
        if sorted(phone_digits(x) for x in got.phones) != sorted(phone_digits(x) for x in e.phones):
            problems.append(f"{e.name!r} has phone numbers {got.phones or 'none'}, expected {e.phones or 'none'}")
        if sorted(x.casefold() for x in got.emails) != sorted(x.casefold() for x in e.emails):
            problems.append(f"{e.name!r} has e-mails {got.emails or 'none'}, expected {e.emails or 'none'}")
    names = {name_key(e.name) for e in expected}
    extra = [p.describe() for p in found if name_key(p.name) not in names]
    if extra:
        problems.append("other contacts: " + ", ".join(extra[:5]))
    return Verdict.check(not problems, want, "; ".join(problems) or "so")


@evaluator("android_contacts_are")
def android_contacts_are(state: FinalState, contacts: list[dict], platform: str | None = None) -> Verdict:
    """The device's contacts (ContactsContract raw contacts not deleted, with their Data rows) are exactly
    `contacts` — `[{"name", "phones": [...], "emails": [...]}]` (or `phone`/`email` for one) — each once: the set-up
    made the others, so a lost, changed, duplicated or extra contact fails."""
    return compare_people(read_contacts(state, platform), _expected_people(contacts))


# vCard (RFC 2426 for 3.0; the vCard 2.1 specification of versit for 2.1; RFC 6350 for 4.0)
def _unfold(text: str) -> list[str]:
    """Logical lines of a vCard: folded lines (CRLF/LF then a space or tab) joined; quoted-printable soft line
    breaks (a line ending in `=` of a QUOTED-PRINTABLE value) joined too."""
    lines: list[str] = []
    for line in text.replace("\r\n", "\n").replace("\r", "\n").split("\n"):
        if lines and line[:1] in (" ", "\t"):
            lines[-1] += line[1:]
        elif lines and lines[-1].endswith("=") and "QUOTED-PRINTABLE" in lines[-1].split(":", 1)[0].upper():
            lines[-1] = lines[-1][:-1] + line
        else:
            lines.append(line)
    return [ln for ln in lines if ln.strip()]


def _vcard_value(params: list[str], value: str) -> str:
    upper = [p.upper() for p in params]
    if "ENCODING=QUOTED-PRINTABLE" in upper or "QUOTED-PRINTABLE" in upper:
        charset = next((p.split("=", 1)[1] for p in params if p.upper().startswith("CHARSET=")), "UTF-8")
        value = quopri.decodestring(value.encode("latin-1", "replace")).decode(charset, "replace")
    return value.replace("\\,", ",").replace("\\;", ";").replace("\\n", "\n").replace("\\N", "\n") \
        .replace("\\\\", "\\")


def parse_vcards(data: bytes) -> list[Person]:
    """The people of a vCard file (versions 2.1, 3.0, 4.0): FN (else N as "Given Family"), TEL and EMAIL values.
    Raises ValueError when the file is not vCards (no BEGIN:VCARD ... VERSION ... END:VCARD)."""
    text = data.decode("utf-8-sig", "replace")
    lines = _unfold(text)
    if not lines or lines[0].strip().upper() != "BEGIN:VCARD":
        raise ValueError(f"not a vCard file (it starts {_short(text[:40])})")
    people: list[Person] = []
    card: dict[str, Any] | None = None
    for line in lines:
        head, sep, value = line.partition(":")
        if not sep:
            raise ValueError(f"not a vCard line: {_short(line, 60)}")
        name, *params = head.split(";")
        prop = name.split(".")[-1].upper()   # group.TEL → TEL
        if prop == "BEGIN" and value.strip().upper() == "VCARD":
            if card is not None:
                raise ValueError("BEGIN:VCARD inside a vCard")
            card = {"version": None, "fn": None, "n": None, "tel": [], "email": []}
        elif card is None:
            raise ValueError(f"a property outside BEGIN:VCARD/END:VCARD: {_short(line, 60)}")
        elif prop == "END" and value.strip().upper() == "VCARD":
            if card["version"] not in ("2.1", "3.0", "4.0"):
                raise ValueError(f"a vCard without VERSION 2.1, 3.0 or 4.0 (VERSION {card['version']!r})")
            fn = card["fn"]
            if not fn and card["n"]:
                parts = (card["n"].split(";") + ["", "", "", "", ""])[:5]
                fn = " ".join(x for x in (parts[3], parts[1], parts[2], parts[0], parts[4]) if x)
            people.append(Person(" ".join((fn or "").split()), card["tel"], card["email"]))
            card = None
        elif prop == "VERSION":
            card["version"] = value.strip()
        elif prop == "FN":
            card["fn"] = _vcard_value(params, value)
        elif prop == "N":
            card["n"] = _vcard_value(params, value)
        elif prop == "TEL":
            card["tel"].append(_vcard_value(params, value).removeprefix("tel:").strip())
        elif prop == "EMAIL":
            card["email"].append(_vcard_value(params, value).strip())
    if card is not None:
        raise ValueError("a vCard without END:VCARD")
    return people


@evaluator("android_vcard_has")
def android_vcard_has(state: FinalState, path: str, contacts: list[dict], platform: str | None = None) -> Verdict:
    """`path` is a vCard file (its real format, not its name) holding exactly `contacts` (as for
    `android_contacts_are`: each once, with its numbers and e-mails; nobody else)."""
    expected = _expected_people(contacts)
    return judge_file(state, path, f"a vCard file at {path} with {len(expected)} contacts", parse_vcards,
                      lambda people: compare_people(people, expected, f"the vCards of {path}"), platform)


@evaluator("android_contacts_imported")
def android_contacts_imported(state: FinalState, path: str, contacts: list[dict],
                              platform: str | None = None) -> Verdict:
    """The vCards of `path` (as set up: the template lists it under `baseline`; fed by an earlier subtask, as it
    is now) were imported: the device's contacts are exactly `contacts` (those there before, unchanged) plus one
    contact per vCard with its numbers and e-mails — none missing, none twice."""
    data = state.baseline(path, platform) or state.pull(path, platform)
    if data is None:
        return Verdict.check(False, f"the contacts of {path} imported", f"no file at {path}")
    try:
        cards = parse_vcards(data)
    except ValueError as exc:
        return Verdict.check(False, f"the contacts of {path} imported", f"{path} unreadable: {exc}")
    return compare_people(read_contacts(state, platform), _expected_people(contacts) + cards,
                          f"the {len(contacts)} contacts there before and the {len(cards)} of {path}")


# -- messages and calls ---------------------------------------------------------------------------------------
TELEPHONY = "com.android.providers.telephony"
SMS_DB = "mmssms.db"
SMS_QUERY = "SELECT _id, thread_id, address, body, type, date FROM sms ORDER BY _id"
# Telephony.Sms.MESSAGE_TYPE_*
SMS_TYPES = {1: "received", 2: "sent", 3: "draft", 4: "outbox", 5: "failed", 6: "queued"}
OUTGOING = {2, 4, 5, 6}   # sent, or handed to the modem (outbox, queued, failed to deliver): the user sent it


def read_sms(state: FinalState, platform: str | None = None) -> list[dict]:
    """Every row of the `sms` table of the telephony provider's database (root: adbd as root or `su`)."""
    device = state.device(platform)
    if not hasattr(device, "query_database"):
        raise InfrastructureError(f"the {device.platform} device cannot read app databases")
    return device.query_database(TELEPHONY, SMS_DB, SMS_QUERY)


def check_sms(rows: list[dict], to: str, body: str, inbox: list[dict] | None = None) -> Verdict:
    """Exactly one message was sent to `to` (digits compared) with the text `body` (surrounding spaces aside), no
    message was sent to anyone else, and every message of `inbox` (`{"address", "body"}`) is still there."""
    want = f"one text message {_short(body)} sent to {to}, nothing else sent" + (
        f", the {len(inbox)} received messages kept" if inbox else "")
    out = [r for r in rows if int(r.get("type") or 0) in OUTGOING]
    drafts = [r for r in rows if int(r.get("type") or 0) == 3]
    to_them = [r for r in out if phone_digits(r.get("address") or "") == phone_digits(to)]
    others = [r for r in out if r not in to_them]
    problems = []
    right = [r for r in to_them if (r.get("body") or "").strip() == str(body).strip()]
    if not to_them:
        hint = ""
        if any(phone_digits(r.get("address") or "") == phone_digits(to) for r in drafts):
            hint = " (only a draft to them, never sent)"
        problems.append(f"nothing sent to {to}{hint}")
    elif not right:
        problems.append(f"sent to {to}: {_short((to_them[0].get('body') or ''), 80)} instead")
    elif len(to_them) > 1:
        problems.append(f"{len(to_them)} messages sent to {to}")
    if others:
        problems.append("also sent to " + ", ".join(f"{r.get('address')}: {_short(r.get('body') or '', 40)}"
                                                   for r in others[:3]))
    received = [r for r in rows if int(r.get("type") or 0) == 1]
    for m in inbox or []:
        if not any(phone_digits(r.get("address") or "") == phone_digits(m["address"])
                   and (r.get("body") or "") == m["body"] for r in received):
            problems.append(f"the message from {m['address']} ({_short(m['body'], 40)}) gone or changed")
    kind = SMS_TYPES.get(int(right[0].get("type") or 0), "?") if right else ""
    return Verdict.check(not problems, want, "; ".join(problems) or f"so ({kind})")


@evaluator("android_sms_sent")
def android_sms_sent(state: FinalState, to: str, body: str, inbox: list[dict] | None = None,
                     platform: str | None = None) -> Verdict:
    """One SMS with the text `body` was sent to `to` (a `Telephony.Sms` row of type sent, or outbox/queued/failed:
    handed to the modem) and to nobody else; the received messages the set-up made (`inbox`) are still there. A
    draft is not a sent message. Read from `mmssms.db` with root (drafts are hidden from non-default apps)."""
    return check_sms(read_sms(state, platform), str(to), str(body), inbox)


CALLS = "content://call_log/calls"
CALL_TYPES = {1: "incoming", 2: "outgoing", 3: "missed", 4: "voicemail", 5: "rejected", 6: "blocked"}


def check_calls(rows: list[dict], number: str, kept: list[dict] | None = None) -> Verdict:
    """Exactly one outgoing call (`CallLog.Calls.TYPE` 2) to `number` (digits compared), no outgoing call to
    another number, and every call of `kept` (`{"number", "type"}`) still in the log."""
    want = f"one outgoing call to {number} in the call log" + (f", the {len(kept)} earlier calls kept" if kept else "")
    problems = []
    outgoing = [r for r in rows if (r.get("type") or "") == "2"]
    mine = [r for r in outgoing if phone_digits(r.get("number") or "") == phone_digits(number)]
    if not mine:
        other_kinds = [CALL_TYPES.get(int(r.get("type") or 0), r.get("type")) for r in rows
                       if phone_digits(r.get("number") or "") == phone_digits(number)]
        problems.append(f"no outgoing call to {number}" + (f" (only {', '.join(other_kinds)})" if other_kinds else ""))
    elif len(mine) > 1:
        problems.append(f"{len(mine)} calls to {number}")
    wrong = [r.get("number") for r in outgoing if r not in mine]
    if wrong:
        problems.append(f"also called {', '.join(str(w) for w in wrong[:3])}")
    for k in kept or []:
        if not any(phone_digits(r.get("number") or "") == phone_digits(k["number"])
                   and (r.get("type") or "") == str(k["type"]) for r in rows):
            problems.append(f"the {CALL_TYPES.get(int(k['type']), k['type'])} call of {k['number']} gone")
    return Verdict.check(not problems, want, "; ".join(problems) or "so")


@evaluator("android_call_made")
def android_call_made(state: FinalState, number: str, kept: list[dict] | None = None,
                      platform: str | None = None) -> Verdict:
    """The call log (`content://call_log/calls`, read as root: READ_CALL_LOG) has one outgoing call to `number`
    and no other outgoing call, and the calls the set-up logged (`kept`) are still there. The system's Telecom
    service writes the row when the call ends, whichever dialer placed it."""
    rows = content_rows(state, CALLS, ["number", "type", "date", "duration"], root=True, platform=platform)
    return check_calls(rows, str(number), kept)


# -- alarms ----------------------------------------------------------------------------------------------------
NOW_RE = re.compile(r"nowRTC=(\d+)")
NEXT_ALARM_RE = re.compile(r"user:(\d+) pendingSend:\w+ time:(\d+)(?: = (\d{4}-\d\d-\d\d \d\d:\d\d:\d\d)\.\d+)?")


def parse_next_alarm(dump: str, user: int = 0) -> tuple[int | None, int, datetime | None]:
    """(now in ms, the next alarm clock's trigger time in ms or 0, its local wall-clock time) from `dumpsys alarm`
    (AlarmManagerService: `nowRTC=<ms>=...` and, under `Next alarm clock information:`, `user:<id> pendingSend:<b>
    time:<ms> = yyyy-MM-dd HH:mm:ss.SSS = <in>`)."""
    now_m = NOW_RE.search(dump)
    now = int(now_m.group(1)) if now_m else None
    section = dump.split("Next alarm clock information:", 1)
    for m in NEXT_ALARM_RE.finditer(section[1] if len(section) > 1 else ""):
        if int(m.group(1)) == user:
            when = datetime.strptime(m.group(3), "%Y-%m-%d %H:%M:%S") if m.group(3) else None
            return now, int(m.group(2)), when
    return now, 0, None


def check_next_alarm(now: int | None, trigger: int, local: datetime | None, hour: int, minute: int) -> Verdict:
    """The next alarm clock rings at `hour`:`minute` local time within the next 24 hours (a one-off or the next
    occurrence of a repeating alarm)."""
    want = f"the next alarm at {hour:02d}:{minute:02d} (within 24 h)"
    if not trigger or local is None:
        return Verdict.check(False, want, "no alarm set")
    found = f"the next alarm at {local:%H:%M} on {local:%Y-%m-%d}"
    if (local.hour, local.minute) != (hour, minute):
        return Verdict.check(False, want, found)
    if now is not None and not 0 < trigger - now <= 24 * 3600 * 1000:
        return Verdict.check(False, want, found + f" ({(trigger - now) / 3600000:.1f} h from now)")
    return Verdict.check(True, want, found)


@evaluator("android_next_alarm")
def android_next_alarm(state: FinalState, hour: int, minute: int, platform: str | None = None) -> Verdict:
    """The next alarm clock (`AlarmManager.getNextAlarmClock()`, which the Clock app sets for its next enabled
    alarm; printed by `dumpsys alarm`) rings at `hour`:`minute` device-local time within 24 hours. The set-up
    clears the Clock app's alarms, so the alarm is the agent's."""
    now, trigger, local = parse_next_alarm(_run(state, "dumpsys alarm", platform=platform))
    return check_next_alarm(now, trigger, local, int(hour), int(minute))


# -- calendar --------------------------------------------------------------------------------------------------
CALENDARS = "content://com.android.calendar/calendars"
EVENTS = "content://com.android.calendar/events"


def _norm_local(when: str) -> str:
    """`2026-03-12 9:00` → `2026-03-12 09:00` (what `date -d` reads)."""
    d, _, t = str(when).strip().partition(" ")
    hh, _, mm = (t or "0:00").partition(":")
    return f"{d} {int(hh):02d}:{int(mm or 0):02d}"


def device_epoch_ms(state: FinalState, when: str, platform: str | None = None) -> int:
    """Epoch milliseconds of the device-local wall-clock time `when` (`YYYY-MM-DD HH:MM`), by the device's own
    time zone rules (toybox `date -d`)."""
    out = _run(state, f"date -d {q(_norm_local(when))} +%s", platform=platform).strip()
    if not out.isdigit():
        raise InfrastructureError(f"android: date -d {when!r} printed {out!r}")
    return int(out) * 1000


def check_events(rows: list[dict], expected: list[dict]) -> Verdict:
    """`rows` (Events with `title`, `dtstart`, `dtend`, `allDay`) are exactly `expected` (`{"title", "start",
    "end"}` in epoch ms, shown as `{"when"}`): each title once, starting and ending within a minute of the asked
    times, not all-day, and no other event."""
    want = "the calendar's events exactly: " + "; ".join(f"{e['title']!r} {e['when']}" for e in expected)
    problems = []
    for e in expected:
        hits = [r for r in rows if (r.get("title") or "").strip().casefold() == str(e["title"]).strip().casefold()]
        if not hits:
            problems.append(f"no event {e['title']!r}")
            continue
        good = [r for r in hits if (r.get("allDay") or "0") == "0"
                and abs(int(r.get("dtstart") or 0) - e["start"]) < 60000
                and abs(int(r.get("dtend") or 0) - e["end"]) < 60000]
        if not good:
            r = hits[0]
            start = int(r.get("dtstart") or 0)
            end = int(r.get("dtend") or 0)
            problems.append(f"{e['title']!r} " + ("all-day" if (r.get("allDay") or "0") != "0" else
                            f"starts {(start - e['start']) / 60000:+.0f} min and ends {(end - e['end']) / 60000:+.0f} "
                            "min from the asked times"))
        elif len(hits) > 1:
            problems.append(f"{len(hits)} events {e['title']!r}")
    titles = {str(e["title"]).strip().casefold() for e in expected}
    extra = [r.get("title") for r in rows if (r.get("title") or "").strip().casefold() not in titles]
    if extra:
        problems.append(f"other events {extra[:5]}")
    return Verdict.check(not problems, want, "; ".join(problems) or "so")


@evaluator("android_calendar_events")
def android_calendar_events(state: FinalState, calendar: str, events: list[dict],
                            platform: str | None = None) -> Verdict:
    """The events of the calendar named `calendar` (`CalendarContract.Events` rows not deleted) are exactly
    `events`: `[{"title", "start": "YYYY-MM-DD HH:MM", "minutes": N}]` in device-local time — the new one asked
    for and the ones the set-up made, unchanged — each within a minute of its times."""
    cals = content_rows(state, CALENDARS, ["_id", "name"], platform=platform)
    ids = [c["_id"] for c in cals if (c.get("name") or "") == calendar]
    if not ids:
        return Verdict.check(False, f"a calendar named {calendar!r}", f"calendars {[c.get('name') for c in cals]}")
    rows = [r for r in content_rows(state, EVENTS, ["_id", "calendar_id", "title", "dtstart", "dtend", "allDay",
                                                     "deleted"], platform=platform)
            if r.get("calendar_id") in ids and (r.get("deleted") or "0") == "0"]
    expected = []
    for e in events:
        start = device_epoch_ms(state, e["start"], platform)
        expected.append({"title": e["title"], "start": start, "end": start + int(e["minutes"]) * 60000,
                         "when": f"{_norm_local(e['start'])} for {int(e['minutes'])} min"})
    return check_events(rows, expected)


# -- files (a deletion is `folders.file_deleted`) -----------------------------------------------------------
def check_photo(data: bytes | None, path: str, decoys: dict[str, bytes], min_side: int = 240) -> Verdict:
    """`data` is a photo: a real JPEG (decoded) at least `min_side` pixels on its short side, and not one of the
    pictures that were on the device before (`decoys`: path → bytes)."""
    from PIL import Image

    want = f"a new JPEG photo at {path}"
    if data is None:
        return Verdict.check(False, want, f"no file at {path}")
    try:
        with Image.open(io.BytesIO(data)) as img:
            fmt, size = img.format, img.size
            img.load()
    except Exception as exc:  # noqa: BLE001 - a file that is not an image is a finding
        return Verdict.check(False, want, f"{path} is not a picture ({exc.__class__.__name__})")
    if fmt != "JPEG":
        return Verdict.check(False, want, f"a {fmt} picture, not a JPEG")
    if min(size) < min_side:
        return Verdict.check(False, want, f"a {size[0]}x{size[1]} JPEG (a photo is at least {min_side} px)")
    for name, old in decoys.items():
        if old == data:
            return Verdict.check(False, want, f"a copy of {name}, which was on the device before")
    return Verdict.check(True, want, f"a {size[0]}x{size[1]} JPEG")


@evaluator("android_photo_taken")
def android_photo_taken(state: FinalState, path: str, decoys: list[str] | None = None,
                        camera_folder: str = "/sdcard/DCIM/Camera", platform: str | None = None) -> Verdict:
    """`path` is a photo taken during the task (a decodable JPEG of camera size that is none of the pictures the
    set-up left, `decoys`, listed under `baseline`), moved there: no file with its bytes is left in
    `camera_folder`."""
    data = state.pull(path, platform)
    olds = {d: b for d in decoys or [] if (b := state.baseline(d, platform)) is not None}
    verdict = check_photo(data, path, olds)
    if not verdict.passed or data is None:
        return verdict
    listing = state.run(f"ls -1 {q(camera_folder)} 2>/dev/null", platform).stdout.split()
    for name in listing:
        other = f"{camera_folder.rstrip('/')}/{name}"
        if other != path and state.pull(other, platform) == data:
            return Verdict.check(False, f"the photo moved to {path}", f"a copy still at {other} (copied, not moved)")
    return verdict


def _note_lines(text: str) -> list[str]:
    return [" ".join(line.split()) for line in text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
            if line.strip()]


def check_note(text: str, lines: list[str], title: str | None = None) -> Verdict:
    """The non-blank lines of `text` (spaces collapsed) are exactly `lines`, optionally after one heading line that
    is `title` itself (as `title` or a Markdown `# title`, which a note editor may put first)."""
    want = f"the note to read exactly {lines!r}" + (f" (a first line {title!r} allowed)" if title else "")
    got = _note_lines(text)
    if title and got and got[0].lstrip("#").strip().casefold() == str(title).strip().casefold() \
            and got[1:] == [" ".join(str(x).split()) for x in lines]:
        return Verdict.check(True, want, "so, under its title")
    expected = [" ".join(str(x).split()) for x in lines]
    return Verdict.check(got == expected, want, "so" if got == expected else _short(got, 200))


@evaluator("android_note_is")
def android_note_is(state: FinalState, path: str, lines: list[str], title: str | None = None,
                    platform: str | None = None) -> Verdict:
    """The text file `path` holds exactly `lines` (blank lines and extra spaces aside; a heading line with the
    note's `title` allowed first), as UTF-8 text."""
    def parse(data: bytes) -> str:
        return data.decode("utf-8")
    return judge_file(state, path, f"a UTF-8 text note at {path}", parse,
                      lambda text: check_note(text, [str(x) for x in lines], title), platform)


# -- Chrome ----------------------------------------------------------------------------------------------------
CHROME_BOOKMARKS = "/data/data/com.android.chrome/app_chrome/Default/Bookmarks"
SETTLE_SECONDS = 6.0


@evaluator("android_chrome_bookmark")
def android_chrome_bookmark(state: FinalState, url: str, name: str | None = None,
                            others: list[str] | None = None, path: str = CHROME_BOOKMARKS,
                            platform: str | None = None) -> Verdict:
    """Chrome has a bookmark of `url` (titled `name`, when given) in its profile's `Bookmarks` file, which Chrome
    wrote (its checksum matches: a hand-edited file does not count), and none of the `others` URLs (pages of the
    same site the instruction did not ask for). Chrome saves the file about 2.5 s after a change, so it is read
    again for a few seconds before a missing bookmark is reported."""
    deadline = time.monotonic() + SETTLE_SECONDS
    while True:
        res = state.run(f"cat {q(path)}", platform, user="root")
        text = res.stdout if res.returncode == 0 and res.stdout.strip() else None
        verdict = check_bookmark(text, url, name)
        if verdict.passed or time.monotonic() > deadline:
            break
        time.sleep(0.5)
    if not verdict.passed or not others:
        return verdict
    from jarvis_pytest.evaluators.browser import bookmarks

    marks = bookmarks(text or "{}")
    extra = [u for _, u in marks if u in others]
    return Verdict.check(not extra, f"a bookmark of {url}" + (f" named {name!r}" if name else "") +
                         f" and none of {', '.join(others)}",
                         f"also bookmarked {extra}" if extra else repr(marks[:10]))
