"""The Android evaluators (`jarvis_pytest/evaluators/android.py`) on device output built to the formats AOSP's
tools print (no Android device can run here): `content query` rows as `cmds/content/.../Content.java` prints them
(`Row: n col=value, ...`, `NULL`, `No result found.`), `settings get` (`null` when unset), `cmd uimode night`
(UiModeManagerService's shell: `Night mode: <mode>`), `dumpsys bluetooth_manager` (BluetoothManagerService.dump:
`Bluetooth Status` / `  enabled: true`), `dumpsys alarm` (AlarmManagerService.dumpImpl: `nowRTC=<ms>=<date>` and
`Next alarm clock information:` / `user:0 pendingSend:false time:<ms> = yyyy-MM-dd HH:mm:ss.SSS = <in>`), the
telephony provider's `sms` table (Telephony.Sms columns) and vCards in the versions phones write (2.1 with
quoted-printable, 3.0, 4.0). For each check the state a careful person leaves passes — whatever format the app
stores a number or a name in — and near misses fail with a reason naming what is wrong. The commands the
evaluators send to the device are checked to be valid for Android's shell (mksh)."""

from __future__ import annotations

import io
import re
import shutil
import sqlite3
import subprocess

import pytest
from PIL import Image

from jarvis_pytest.devices.base import CommandResult
from jarvis_pytest.errors import InfrastructureError
from jarvis_pytest.evaluators import android as A
from jarvis_pytest.evaluators import get_evaluator
from jarvis_pytest.evaluators.browser import bookmarks_checksum
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.generators import generate
from tests.file_state import posix_facts_reply

MKSH = shutil.which("mksh")


class FakeAndroid:
    """A device answering commands from (regex → stdout) pairs, holding `files`, and an `sms` table; it records
    every command with its user."""

    platform = "android"

    def __init__(self, replies: dict[str, str] | None = None, files: dict[str, bytes] | None = None,
                 sms: list[tuple] | None = None):
        self.replies = replies or {}
        self.files = dict(files or {})
        self.sms = sms or []
        self.sent: list[tuple[str, str | None]] = []

    def run(self, command: str, *, timeout: float = 60.0, user: str | None = None) -> CommandResult:
        self.sent.append((command, user))
        facts = posix_facts_reply(command, self.files)  # the file-facts script, answered from `files`
        if facts is not None:
            return CommandResult(0, facts, "")
        for pattern, reply in self.replies.items():
            if re.search(pattern, command):
                return CommandResult(0, reply, "")
        return CommandResult(1, "", f"no reply for {command}")

    def exists(self, path: str) -> bool:
        return path in self.files

    def download(self, path: str) -> bytes:
        return self.files[path]

    def query_database(self, package: str, database: str, sql: str, params: tuple = ()) -> list[dict]:
        assert (package, database) == ("com.android.providers.telephony", "mmssms.db")
        con = sqlite3.connect(":memory:")
        con.row_factory = sqlite3.Row
        con.execute("CREATE TABLE sms (_id INTEGER PRIMARY KEY, thread_id INTEGER, address TEXT, body TEXT, "
                    "type INTEGER, date INTEGER, read INTEGER)")
        con.executemany("INSERT INTO sms (thread_id, address, body, type, date) VALUES (?, ?, ?, ?, ?)", self.sms)
        return [dict(r) for r in con.execute(sql, params)]


def state_of(device: FakeAndroid, baselines: dict[str, bytes] | None = None) -> FinalState:
    return FinalState(platform="android", devices={"android": device},
                      baselines={("android", p): b for p, b in (baselines or {}).items()})


def rows(*records: dict) -> str:
    """`content query` output for `records` (Content.java: `Row: n col=value, ...`, NULL for None)."""
    if not records:
        return "No result found.\n"
    return "".join(f"Row: {n} " + ", ".join(f"{k}={'NULL' if v is None else v}" for k, v in r.items()) + "\n"
                   for n, r in enumerate(records))


@pytest.fixture(autouse=True)
def commands_are_valid_for_mksh(request):
    """Every command an evaluator sends parses in mksh, Android's /system/bin/sh."""
    sent: list[str] = []
    orig = FakeAndroid.run

    def spy(self, command, **kw):
        sent.append(command)
        return orig(self, command, **kw)

    FakeAndroid.run = spy
    try:
        yield
    finally:
        FakeAndroid.run = orig
    if MKSH:
        for cmd in sent:
            res = subprocess.run([MKSH, "-n", "-c", cmd], capture_output=True, text=True)
            assert res.returncode == 0, f"{cmd!r}: {res.stderr}"


# -- settings --------------------------------------------------------------------------------------------------
def test_setting_is_typed_and_the_untouched_settings_are_checked():
    ev = get_evaluator("android_setting_is")
    dev = FakeAndroid({r"settings get system screen_brightness$": "255\n",
                       r"settings get system screen_brightness_mode$": "0\n",
                       r"settings get system screen_off_timeout$": "600000\n"})
    args = {"namespace": "system", "key": "screen_brightness", "expected": "maximum", "values": {"maximum": 255},
            "unchanged": [["system", "screen_brightness_mode", 0], ["system", "screen_off_timeout", 600000]]}
    v = ev(state_of(dev), **args)
    assert v.passed, v.reason
    assert "screen_brightness = 255 (maximum)" in v.reason
    dev.replies[r"settings get system screen_brightness_mode$"] = "1\n"
    v = ev(state_of(dev), **args)
    assert not v.passed and "screen_brightness_mode = '1' (set up as 0: changed)" in v.reason
    dev.replies[r"settings get system screen_brightness$"] = "max\n"
    v = ev(state_of(dev), **args)
    assert not v.passed and "not an integer" in v.reason
    dev.replies[r"settings get system screen_brightness$"] = "null\n"
    assert "unset" in ev(state_of(dev), **args).reason


def test_float_setting_with_tolerance_and_an_unset_key():
    ev = get_evaluator("android_setting_is")
    for stored, ok in (("1.15", True), ("1.1500001", True), ("1.3", False), ("Large", False)):
        dev = FakeAndroid({r"font_scale$": stored + "\n", r"display_density_forced$": "\n"})
        v = ev(state_of(dev), namespace="system", key="font_scale", expected="Large", kind="float", tolerance=0.001,
               values={"Large": 1.15}, unchanged=[["secure", "display_density_forced", None]])
        assert v.passed is ok, (stored, v.reason)
    dev = FakeAndroid({r"font_scale$": "1.15\n", r"display_density_forced$": "480\n"})
    v = ev(state_of(dev), namespace="system", key="font_scale", expected=1.15, kind="float", tolerance=0.001,
           unchanged=[["secure", "display_density_forced", None]])
    assert not v.passed and "display_density_forced = '480' (unset at set-up: changed)" in v.reason
    with pytest.raises(ValueError):
        ev(state_of(dev), namespace="systen", key="font_scale", expected=1)


def test_setting_that_cannot_be_read_is_an_infrastructure_error():
    with pytest.raises(InfrastructureError, match="settings get system font_scale"):
        get_evaluator("android_setting_is")(state_of(FakeAndroid()), namespace="system", key="font_scale",
                                            expected=1.0, kind="float")


@pytest.mark.parametrize("service, stored, ok", [
    ("Night mode: yes\n", "2", True), ("Night mode: no\n", "1", False), ("Night mode: auto\n", "0", False),
    ("Night mode: custom\n", "3", False), ("Night mode: yes\n", "1", False)])
def test_dark_theme_needs_the_service_and_the_stored_mode(service, stored, ok):
    dev = FakeAndroid({r"^cmd uimode night$": service, r"ui_night_mode$": stored + "\n"})
    v = get_evaluator("android_dark_theme")(state_of(dev), on=True)
    assert v.passed is ok, v.reason
    assert A.parse_night_mode(service) == service.split(":")[1].strip()


def test_bluetooth_needs_the_adapter_not_only_the_flag():
    ev = get_evaluator("android_bluetooth")
    on = "Bluetooth Status\n  enabled: true\n  state: ON\n  address: 3C:5A:B4:01:02:03\n  name: Pixel\n"
    off = on.replace("enabled: true", "enabled: false").replace("ON", "OFF")
    for dump, flag, ok in ((on, "1", True), (off, "1", False), (on, "0", False)):
        dev = FakeAndroid({r"dumpsys bluetooth_manager": dump, r"bluetooth_on$": flag + "\n",
                           r"wifi_on$": "1\n"})
        v = ev(state_of(dev), on=True, unchanged=[["global", "wifi_on", 1]])
        assert v.passed is ok, v.reason
    dev = FakeAndroid({r"dumpsys bluetooth_manager": on, r"bluetooth_on$": "1\n", r"wifi_on$": "0\n"})
    assert "wifi_on = '0'" in ev(state_of(dev), on=True, unchanged=[["global", "wifi_on", 1]]).reason
    assert A.parse_bluetooth_enabled("nothing here") is None


# -- contacts and vCards ---------------------------------------------------------------------------------------
RAW = [{"_id": 1, "display_name": "Alice Moreau", "deleted": 0}, {"_id": 2, "display_name": "Grace Liu", "deleted": 0},
       {"_id": 3, "display_name": "Old Friend", "deleted": 1}]
DATA = [{"raw_contact_id": 1, "mimetype": A.MIME_NAME, "data1": "Alice Moreau"},
        {"raw_contact_id": 1, "mimetype": A.MIME_PHONE, "data1": "+1 555-310-2211"},
        {"raw_contact_id": 2, "mimetype": A.MIME_NAME, "data1": "Grace Liu"},
        {"raw_contact_id": 2, "mimetype": A.MIME_PHONE, "data1": "(555) 347-5919"},
        {"raw_contact_id": 2, "mimetype": A.MIME_EMAIL, "data1": "Meadow.54@Example.com"},
        {"raw_contact_id": 3, "mimetype": A.MIME_NAME, "data1": "Old Friend"}]
EXPECTED = [{"name": "Alice Moreau", "phones": ["+1 555 310 2211"]},
            {"name": "Grace Liu", "phones": ["+1 555 347 5919"], "emails": ["meadow.54@example.com"]}]


def contacts_device(raw=RAW, data=DATA) -> FakeAndroid:
    return FakeAndroid({r"content query --uri content://com.android.contacts/raw_contacts ": rows(*raw),
                        r"content query --uri content://com.android.contacts/data ": rows(*data)})


def test_contacts_in_the_apps_own_formats_pass_and_a_deleted_raw_contact_does_not_count():
    v = get_evaluator("android_contacts_are")(state_of(contacts_device()), contacts=EXPECTED)
    assert v.passed, v.reason
    assert A.phone_digits("+1 (555) 347-5919") == A.phone_digits("555.347.5919") == "5553475919"


@pytest.mark.parametrize("change, needle", [
    (lambda raw, data: (raw, [d for d in data if d["mimetype"] != A.MIME_EMAIL]), "has e-mails none"),
    (lambda raw, data: (raw, [dict(d, data1="+1 555 347 5918") if d["data1"] == "(555) 347-5919" else d
                              for d in data]), "has phone numbers ['+1 555 347 5918']"),
    (lambda raw, data: (raw + [{"_id": 4, "display_name": "Grace Liu", "deleted": 0}],
                        data + [{"raw_contact_id": 4, "mimetype": A.MIME_NAME, "data1": "Grace Liu"}]),
     "2 contacts named 'Grace Liu' (a duplicate)"),
    (lambda raw, data: ([r for r in raw if r["_id"] != 1], [d for d in data if d["raw_contact_id"] != 1]),
     "no contact named 'Alice Moreau'"),
    (lambda raw, data: (raw + [{"_id": 5, "display_name": "Zed", "deleted": 0}], data), "other contacts: 'Zed'"),
])
def test_contacts_near_misses_fail_naming_the_difference(change, needle):
    raw, data = change(list(RAW), list(DATA))
    v = get_evaluator("android_contacts_are")(state_of(contacts_device(raw, data)), contacts=EXPECTED)
    assert not v.passed and needle in v.reason, v.reason


VCARD_21 = (b"BEGIN:VCARD\r\nVERSION:2.1\r\nN:Moreau;Alice;;;\r\nFN:Alice Moreau\r\nTEL;CELL:+1 555-310-2211\r\n"
            b"END:VCARD\r\nBEGIN:VCARD\r\nVERSION:2.1\r\nN;CHARSET=UTF-8;ENCODING=QUOTED-PRINTABLE:Li=C3=BA;Gr=\r\n"
            b"ace;;;\r\nTEL;CELL:5553475919\r\nEMAIL;HOME:meadow.54@example.com\r\nEND:VCARD\r\n")
VCARD_30 = ("BEGIN:VCARD\nVERSION:3.0\nFN:Alice Moreau\nN:Moreau;Alice;;;\nitem1.TEL;TYPE=CELL:+1 555 310 2211\n"
            "END:VCARD\nBEGIN:VCARD\nVERSION:3.0\nFN:Grace\n  Liu\nTEL;TYPE=CELL:(555) 347-5919\n"
            "EMAIL;TYPE=INTERNET:meadow.54@example.com\nEND:VCARD\n").encode()
VCARD_40 = ("BEGIN:VCARD\r\nVERSION:4.0\r\nFN:Alice Moreau\r\nTEL;VALUE=uri;TYPE=cell:tel:+1-555-310-2211\r\n"
            "END:VCARD\r\n").encode()


def test_vcards_of_every_version_parse():
    people = A.parse_vcards(VCARD_21)
    assert [p.name for p in people] == ["Alice Moreau", "Grace Liú"]
    assert people[1].phones == ["5553475919"] and people[1].emails == ["meadow.54@example.com"]
    people = A.parse_vcards(VCARD_30)
    assert [p.name for p in people] == ["Alice Moreau", "Grace Liu"]
    assert A.parse_vcards(VCARD_40)[0].phones == ["+1-555-310-2211"]
    assert A.parse_vcards(b"\xef\xbb\xbf" + VCARD_40)[0].name == "Alice Moreau"


@pytest.mark.parametrize("data, needle", [
    (b"Alice Moreau\nGrace Liu\n", "not a vCard file"),
    (b"name,phone\nAlice Moreau,+1 555 310 2211\n", "not a vCard file"),
    (b"BEGIN:VCARD\r\nFN:Alice\r\nEND:VCARD\r\n", "without VERSION"),
    (b"BEGIN:VCARD\r\nVERSION:3.0\r\nFN:Alice\r\n", "without END:VCARD"),
    (b"BEGIN:VCARD\r\nVERSION:3.0\r\nBEGIN:VCARD\r\n", "inside a vCard"),
])
def test_what_is_not_a_vcard_file_is_refused(data, needle):
    with pytest.raises(ValueError, match=needle):
        A.parse_vcards(data)


def test_vcard_file_evaluator_and_the_generator_round_trip():
    ev = get_evaluator("android_vcard_has")
    made = generate("vcard_contacts", {"contacts": [["Alice Moreau", "+1 555 310 2211"],
                                                    ["Grace Liu", "+1 555 347 5919", "meadow.54@example.com"]]})
    assert made.startswith(b"BEGIN:VCARD\r\nVERSION:3.0\r\nN:Moreau;Alice;;;\r\nFN:Alice Moreau\r\n")
    for data in (made, VCARD_30):
        v = ev(state_of(FakeAndroid(files={"/sdcard/Download/c.vcf": data})), path="/sdcard/Download/c.vcf",
               contacts=EXPECTED)
        assert v.passed, v.reason
    v = ev(state_of(FakeAndroid(files={"/sdcard/Download/c.vcf": b"Alice Moreau\n"})),
           path="/sdcard/Download/c.vcf", contacts=EXPECTED)
    assert not v.passed and "unreadable: not a vCard file" in v.reason
    v = ev(state_of(FakeAndroid()), path="/sdcard/Download/c.vcf", contacts=EXPECTED)
    assert not v.passed and "no file at /sdcard/Download/c.vcf" in v.reason
    with pytest.raises(Exception):
        generate("vcard_contacts", {"contacts": []})
    assert generate("vcard_contacts", {"contacts": [["A B", "1"]], "version": "2.1"}).count(b"TEL;CELL:1") == 1


def test_import_expects_the_cards_of_the_file_as_set_up_plus_the_contacts_there_before():
    vcf = generate("vcard_contacts", {"contacts": [["Grace Liu", "+1 555 347 5919", "meadow.54@example.com"]]})
    ev = get_evaluator("android_contacts_imported")
    device = contacts_device()
    device.files["/sdcard/Download/t.vcf"] = vcf
    v = ev(state_of(device, {"/sdcard/Download/t.vcf": vcf}), path="/sdcard/Download/t.vcf", contacts=EXPECTED[:1])
    assert v.passed, v.reason
    device.files["/sdcard/Download/t.vcf"] = b"emptied by the agent"   # the baseline is what counts
    assert ev(state_of(device, {"/sdcard/Download/t.vcf": vcf}), path="/sdcard/Download/t.vcf",
              contacts=EXPECTED[:1]).passed
    v = ev(state_of(contacts_device(RAW[:1], DATA[:2])), path="/sdcard/Download/t.vcf", contacts=EXPECTED[:1])
    assert not v.passed and "no file" in v.reason


# -- messages and calls ----------------------------------------------------------------------------------------
INBOX = [{"address": "+1 555 010 4477", "body": "Are we still on for Saturday?"}]
SEEDED = [(1, "+1 555 010 4477", "Are we still on for Saturday?", 1, 1)]


@pytest.mark.parametrize("extra, ok, needle", [
    ([(2, "+15556153937", "Running ten minutes late, sorry", 2, 5)], True, "so (sent)"),
    ([(2, "(555) 615-3937", " Running ten minutes late, sorry ", 4, 5)], True, "so (outbox)"),
    ([(2, "+1 555 615 3937", "Running ten minutes late, sorry", 3, 5)], False, "only a draft to them"),
    ([(2, "+1 555 615 3937", "Running", 2, 5)], False, "'Running' instead"),
    ([(2, "+1 555 615 3937", "Running ten minutes late, sorry", 2, 5)] * 2, False, "2 messages sent to"),
    ([(2, "+1 555 615 3937", "Running ten minutes late, sorry", 2, 5),
      (3, "+1 555 010 4477", "Running ten minutes late, sorry", 2, 6)], False, "also sent to +1 555 010 4477"),
    ([(2, "+1 555 615 3937", "running ten minutes late, sorry", 2, 5)], False, "instead"),
])
def test_sent_sms_is_read_from_the_telephony_database(extra, ok, needle):
    dev = FakeAndroid(sms=SEEDED + extra)
    v = get_evaluator("android_sms_sent")(state_of(dev), to="+1 555 615 3937", body="Running ten minutes late, sorry",
                                          inbox=INBOX)
    assert v.passed is ok and needle in v.reason, v.reason


def test_sent_sms_with_the_received_message_gone_fails():
    dev = FakeAndroid(sms=[(2, "+1 555 615 3937", "hello", 2, 5)])
    v = get_evaluator("android_sms_sent")(state_of(dev), to="+1 555 615 3937", body="hello", inbox=INBOX)
    assert not v.passed and "the message from +1 555 010 4477" in v.reason
    code = FakeAndroid(sms=[(1, "ParcelPoint", "Your code is 123456.", 1, 1), (2, "+1 555 615 3937", "123456", 2, 2)])
    v = get_evaluator("android_sms_sent")(state_of(code), to="+1 555 615 3937", body=123456,
                                          inbox=[{"address": "ParcelPoint", "body": "Your code is 123456."}])
    assert v.passed, v.reason


CALLS = [{"number": "555-310-2211", "type": 1}, {"number": "555-420-7788", "type": 3}]


@pytest.mark.parametrize("logged, ok, needle", [
    ([{"number": "5552098983", "type": 2}], True, "so"),
    ([{"number": "+1 555-209-8983", "type": 2}], True, "so"),
    ([{"number": "555-209-8983", "type": 1}], False, "(only incoming)"),
    ([], False, "no outgoing call to 555-209-8983"),
    ([{"number": "555-209-8983", "type": 2}, {"number": "555-310-2211", "type": 2}], False, "also called 555-310-2211"),
    ([{"number": "555-209-8983", "type": 2}] * 2, False, "2 calls to"),
])
def test_call_log(logged, ok, needle):
    base = [{"number": c["number"], "type": c["type"], "date": 1, "duration": 3} for c in CALLS]
    made = [{"number": c["number"], "type": c["type"], "date": 2, "duration": 8} for c in logged]
    dev = FakeAndroid({r"^content query --uri content://call_log/calls --projection number:type:date:duration$":
                       rows(*(base + made))})
    v = get_evaluator("android_call_made")(state_of(dev), number="555-209-8983", kept=CALLS)
    assert v.passed is ok and needle in v.reason, v.reason
    assert dev.sent[0][1] == "root"   # the call log needs READ_CALL_LOG: read as root


def test_call_log_without_an_earlier_call_fails():
    dev = FakeAndroid({r"call_log": rows({"number": "555-209-8983", "type": 2, "date": 2, "duration": 8})})
    v = get_evaluator("android_call_made")(state_of(dev), number="555-209-8983", kept=CALLS)
    assert not v.passed and "the incoming call of 555-310-2211 gone" in v.reason


# -- alarms ----------------------------------------------------------------------------------------------------
def alarm_dump(now_ms: int, now_text: str, next_ms: int | None, next_text: str | None) -> str:
    """`dumpsys alarm` as AlarmManagerService.dumpImpl prints the parts the check reads (API 31+ layout)."""
    head = (f"Current Alarm Manager state:\n  Settings:\n    min_futurity=+5s0ms\n\n  nowRTC={now_ms}={now_text} "
            "nowELAPSED=1234567\n  mLastTimeChangeClockTime=0=1970-01-01 00:00:00.000\n\n"
            "  Next alarm clock information: \n")
    line = f"    user:0 pendingSend:false time:{next_ms} = {next_text} = +3h4m0s0ms\n" if next_ms else ""
    return head + line + "\n  Pending user blocked background alarms: \n    none\n"


NOW = 1700000000000   # 2023-11-14 22:13:20 UTC; the texts are device-local (here UTC-5)
NOW_TEXT = "2023-11-14 17:13:20.000"


@pytest.mark.parametrize("when, text, ok, needle", [
    (NOW + 14 * 3600 * 1000 + 26 * 60 * 1000 + 40000, "2023-11-15 07:40:00.000", True, "at 07:40 on 2023-11-15"),
    (NOW + 2 * 3600 * 1000 + 26 * 60 * 1000 + 40000, "2023-11-14 19:40:00.000", False, "the next alarm at 19:40"),
    (NOW + 14 * 3600 * 1000, "2023-11-15 07:13:20.000", False, "the next alarm at 07:13"),
    (NOW + 38 * 3600 * 1000 + 26 * 60 * 1000 + 40000, "2023-11-16 07:40:00.000", False, "h from now"),
    (None, None, False, "no alarm set"),
])
def test_next_alarm(when, text, ok, needle):
    dev = FakeAndroid({r"^dumpsys alarm$": alarm_dump(NOW, NOW_TEXT, when, text)})
    v = get_evaluator("android_next_alarm")(state_of(dev), hour=7, minute=40)
    assert v.passed is ok and needle in v.reason, v.reason


def test_next_alarm_of_another_user_and_a_line_without_its_duration():
    short = ("Next alarm clock information:\n"
                "  user:0 pendingSend:false time:1787740140000 = 2026-08-26 15:59:00.000\n")
    now, trigger, local = A.parse_next_alarm(short)
    assert (now, trigger, f"{local:%H:%M}") == (None, 1787740140000, "15:59")
    other = ("Next alarm clock information: \n"
             "    user:10 pendingSend:false time:1787740140000 = 2026-08-26 15:59:00.000\n")
    assert A.parse_next_alarm(other)[1] == 0
    assert A.parse_next_alarm("Next alarm clock information: \n    user:0 pendingSend:true time:0\n")[1] == 0


# -- calendar --------------------------------------------------------------------------------------------------
def calendar_device(events: list[dict]) -> FakeAndroid:
    return FakeAndroid({
        r"content query --uri content://com.android.calendar/calendars": rows({"_id": 1, "name": "Personal"},
                                                                             {"_id": 3, "name": "Jarvis"}),
        r"content query --uri content://com.android.calendar/events": rows(*events),
        r"^date -d '2026-03-12 09:00' \+%s$": "1773320400\n",    # in America/New_York
        r"^date -d '2026-03-11 18:00' \+%s$": "1773266400\n"})


START, GYM = 1773320400000, 1773266400000


def event(title, start, minutes, cal=3, all_day=0, deleted=0):
    return {"_id": 1, "calendar_id": cal, "title": title, "dtstart": start, "dtend": start + minutes * 60000,
            "allDay": all_day, "deleted": deleted}


WANT = [{"title": "Gym", "start": "2026-03-11 18:00", "minutes": 60},
        {"title": "Team lunch", "start": "2026-03-12 9:00", "minutes": 90}]


@pytest.mark.parametrize("events, ok, needle", [
    ([event("Gym", GYM, 60), event("Team lunch", START, 90)], True, "so"),
    ([event("Gym", GYM, 60), event("team lunch ", START + 30000, 90)], True, "so"),
    ([event("Gym", GYM, 60), event("Team lunch", START, 90), event("Other", START, 30, cal=1)], True, "so"),
    ([event("Gym", GYM, 60), event("Team lunch", START, 90), event("Old", START, 30, deleted=1)], True, "so"),
    ([event("Gym", GYM, 60), event("Team lunch", START + 3600000, 90)], False, "starts +60 min"),
    ([event("Gym", GYM, 60), event("Team lunch", START, 60)], False, "ends -30 min"),
    ([event("Gym", GYM, 60), event("Team lunch", START, 90, all_day=1)], False, "all-day"),
    ([event("Team lunch", START, 90)], False, "no event 'Gym'"),
    ([event("Gym", GYM, 60), event("Team lunch", START, 90), event("Extra", START, 30)], False, "other events"),
    ([event("Gym", GYM, 60)] + [event("Team lunch", START, 90)] * 2, False, "2 events 'Team lunch'"),
])
def test_calendar_events(events, ok, needle):
    v = get_evaluator("android_calendar_events")(state_of(calendar_device(events)), calendar="Jarvis", events=WANT)
    assert v.passed is ok and needle in v.reason, v.reason


def test_calendar_missing():
    dev = FakeAndroid({r"calendars": rows({"_id": 1, "name": "Personal"})})
    v = get_evaluator("android_calendar_events")(state_of(dev), calendar="Jarvis", events=WANT)
    assert not v.passed and "a calendar named 'Jarvis'" in v.reason


# -- files, photos, notes, bookmarks ---------------------------------------------------------------------------
def jpeg(w=1280, h=960, color="#336699") -> bytes:
    buf = io.BytesIO()
    Image.new("RGB", (w, h), color).save(buf, "JPEG")
    return buf.getvalue()


def test_photo_taken():
    ev = get_evaluator("android_photo_taken")
    old = jpeg(800, 600, "#aa0000")
    photo = jpeg()
    png = io.BytesIO()
    Image.new("RGB", (1280, 960)).save(png, "PNG")
    base = {"/sdcard/Pictures/old_photo.jpg": old}
    cases = [({"/sdcard/Pictures/p.jpg": photo}, True, "a 1280x960 JPEG"),
             ({"/sdcard/Pictures/p.jpg": png.getvalue()}, False, "a PNG picture, not a JPEG"),
             ({"/sdcard/Pictures/p.jpg": old}, False, "a copy of /sdcard/Pictures/old_photo.jpg"),
             ({"/sdcard/Pictures/p.jpg": jpeg(200, 150)}, False, "a 200x150 JPEG"),
             ({"/sdcard/Pictures/p.jpg": b"not an image"}, False, "is not a picture"),
             ({"/sdcard/Pictures/p.jpg": photo, "/sdcard/DCIM/Camera/IMG_1.jpg": photo}, False, "copied, not moved"),
             ({}, False, "no file")]
    for files, ok, needle in cases:
        listing = "\n".join(p.rsplit("/", 1)[1] for p in files if p.startswith("/sdcard/DCIM/Camera/"))
        dev = FakeAndroid({r"^ls -1 /sdcard/DCIM/Camera": listing + "\n"}, files={**files, **base})
        v = ev(state_of(dev, base), path="/sdcard/Pictures/p.jpg", decoys=["/sdcard/Pictures/old_photo.jpg"])
        assert v.passed is ok and needle in v.reason, (needle, v.reason)


def test_file_deleted_not_moved_hidden_or_kept_elsewhere():
    """The neutral `file_deleted` on Android (files_delete_screenshot): removed, or in MediaStore's trash (renamed
    `.trashed-<expiry>-<name>` in its own folder), passes; its bytes kept anywhere a user or the shell may keep files
    (PlatformSpec.user_roots), under a hidden name, or as a fake trash name elsewhere, fail; the neighbours must be
    unchanged."""
    ev = get_evaluator("file_deleted")
    shot, keep = b"\x89PNG shot", b"\x89PNG keep"
    folder = "/sdcard/Pictures/Screenshots"
    path, kept = f"{folder}/s.png", f"{folder}/k.png"
    base = {path: shot, kept: keep}

    def verdict(files: dict[str, bytes], baselines=base):
        return ev(state_of(FakeAndroid(files={kept: keep, **files}), baselines), path=path, kept=[kept])

    assert verdict({}).passed
    assert verdict({f"{folder}/.trashed-1700000000-s.png": shot}).passed  # MediaStore's trash
    for where in ("/sdcard/Download/s.png", f"{folder}/.s.png", "/data/local/tmp/s.png",
                  "/sdcard/Download/.trashed-1700000000-s.png", f"{folder}/.trashed-1700000000-other.png",
                  f"{folder}/.trashed-soon-s.png"):
        v = verdict({where: shot})
        assert not v.passed and f"its content still at {where}" in v.reason, (where, v.reason)
    assert "(hidden)" in verdict({f"{folder}/.s.png": shot}).reason
    v = verdict({path: b""})  # emptied, not deleted
    assert not v.passed and f"{path} still there (a file of 0 bytes)" in v.reason
    assert "k.png: gone" in ev(state_of(FakeAndroid(files={}), base), path=path, kept=[kept]).reason
    assert "k.png: it holds other content" in verdict({kept: b"\x89PNG other"}).reason
    # fed by an upstream subtask (no baseline): a file with its bytes may rightly be elsewhere (its source)
    assert verdict({"/sdcard/Download/s.png": shot}, baselines={kept: keep}).passed
    # a file that held the same bytes at set-up (listed under baseline) is no copy the agent made
    twin = f"{folder}/twin.png"
    assert verdict({twin: shot}, baselines={**base, twin: shot}).passed
    sent = FakeAndroid(files={kept: keep})
    ev(state_of(sent, base), path=path, kept=[kept])
    script = next(c for c, _ in sent.sent if c.startswith("f() {"))
    assert "find -H /sdcard -xdev -type f" in script and "find -H /data/local/tmp" in script
    if MKSH:  # the command is valid for Android's shell
        assert subprocess.run([MKSH, "-n", "-c", script]).returncode == 0


@pytest.mark.parametrize("text, ok", [
    ("Buy oat milk\nReturn the books\n", True), ("Buy oat milk\r\n\r\nReturn the books", True),
    ("# errands\n\nBuy oat milk\nReturn the books\n", True), ("errands\nBuy oat milk\nReturn the books", True),
    ("  Buy  oat milk \nReturn the books", True), ("Return the books\nBuy oat milk\n", False),
    ("Buy oat milk\n", False), ("# notes\nBuy oat milk\nReturn the books\n", False), ("", False)])
def test_note_lines(text, ok):
    dev = FakeAndroid(files={"/sdcard/Documents/Markor/errands.txt": text.encode()})
    v = get_evaluator("android_note_is")(state_of(dev), path="/sdcard/Documents/Markor/errands.txt",
                                         lines=["Buy oat milk", "Return the books"], title="errands")
    assert v.passed is ok, (text, v.reason)


def chrome_file(marks: list[tuple[str, str]], checksum: str | None = None) -> str:
    import json

    data = {"roots": {"bookmark_bar": {"children": [], "id": "1", "name": "Bookmarks bar", "type": "folder"},
                      "other": {"children": [], "id": "2", "name": "Other bookmarks", "type": "folder"},
                      "synced": {"children": [{"id": str(4 + i), "name": n, "type": "url", "url": u}
                                              for i, (n, u) in enumerate(marks)],
                                 "id": "3", "name": "Mobile bookmarks", "type": "folder"}}, "version": 1}
    data["checksum"] = checksum or bookmarks_checksum(data)
    return json.dumps(data)


@pytest.mark.parametrize("text, ok, needle", [
    (chrome_file([("Team Handbook", "http://127.0.0.1:8081/")]), True, "Team Handbook"),
    (chrome_file([("Team Handbook", "http://127.0.0.1:8081/")], "0" * 32), False, "edited by hand"),
    (chrome_file([("Older notes", "http://127.0.0.1:8081/other.html")]), False, "Older notes"),
    (chrome_file([("Team Handbook", "http://127.0.0.1:8081/"), ("Older notes", "http://127.0.0.1:8081/other.html")]),
     False, "also bookmarked"),
])
def test_chrome_bookmark(monkeypatch, text, ok, needle):
    monkeypatch.setattr(A, "SETTLE_SECONDS", 0.0)
    dev = FakeAndroid({r"^cat /data/data/com.android.chrome/app_chrome/Default/Bookmarks$": text})
    v = get_evaluator("android_chrome_bookmark")(state_of(dev), url="http://127.0.0.1:8081/", name="Team Handbook",
                                                 others=["http://127.0.0.1:8081/other.html"])
    assert v.passed is ok and needle in v.reason, v.reason
    assert dev.sent[0][1] == "root"


def test_chrome_without_bookmarks_file(monkeypatch):
    monkeypatch.setattr(A, "SETTLE_SECONDS", 0.0)
    v = get_evaluator("android_chrome_bookmark")(state_of(FakeAndroid()), url="http://127.0.0.1:8081/")
    assert not v.passed and "no bookmarks file" in v.reason


def test_content_rows_errors_are_infrastructure_errors():
    dev = FakeAndroid({r"content query": "Error while accessing provider:com.android.contacts\n"})
    with pytest.raises(InfrastructureError, match="content query"):
        A.read_contacts(state_of(dev))


def test_reused_file_evaluators_run_only_what_android_has(tmp_path):
    """The file evaluators the Android templates reuse from files.py/desktop.py pull bytes and, for the kind of a
    file, run `stat -c '%F|%d:%i' --`, which toybox's stat (Android's) prints like GNU's."""
    toybox = shutil.which("toybox")
    if not toybox:
        pytest.skip("toybox not installed: apt-get install toybox")
    f = tmp_path / "a.csv"
    f.write_text("x\n")
    out = subprocess.run([toybox, "stat", "-c", "%F|%d:%i", "--", str(f)], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.startswith("regular file|")
    empty = tmp_path / "e"
    empty.touch()
    out = subprocess.run([toybox, "stat", "-c", "%F|%d:%i", "--", str(empty)], capture_output=True, text=True)
    assert out.stdout.startswith("regular empty file|")   # files.file_kind maps it to "regular file"
