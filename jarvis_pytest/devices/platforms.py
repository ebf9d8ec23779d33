"""The facts of each platform in one place (as AndroidWorld's `env/device_constants.py`): names, screen, paths,
shell, and how a device of the platform fetches and sends files over HTTP. Everything that differs between
Android, Windows and Ubuntu outside a platform's own folder reads it from here, so a new platform is a new entry,
not a new branch in the plugin, the composer or the agents."""

from __future__ import annotations

import ntpath
import posixpath
import shlex
from dataclasses import dataclass
from typing import Literal, Sequence

from jarvis_pytest.errors import ConfigError

PathStyle = Literal["posix", "windows"]
SHELL_TITLE = "jarvis-shell"  # the title of a command line a GUI solution opens (`PlatformSpec.gui_shell_steps`)


@dataclass(frozen=True)
class FileDialog:
    """How a person drives the desktop's file dialog from the keyboard, as a browser shows it (a web page's "Choose
    Files", "Save link as…"): GTK's chooser on Ubuntu. Chromium loads no GTK accessibility bridge, so the dialog is
    not in the accessibility tree: it is awaited by its title read off the screen image (`screen_text`), and what
    it did is read from the page after it closed."""

    type_path: tuple[str, ...]   # in an Open dialog: shows the field that takes a typed path
    open: tuple[str, ...]        # the Open button (its mnemonic; Return in the typed path does not press it)
    save: tuple[str, ...]        # the Save button; the name field has the keyboard and takes a whole path
    open_title: str = "Open File*"  # the dialogs' titles, as the window manager draws them ("Open Files" for a
    save_title: str = "Save File"   # form that takes several)
    shows_within: float = 20.0      # seconds a dialog gets to show


@dataclass(frozen=True)
class PlatformSpec:
    """One platform's facts."""

    name: str                        # android | windows | ubuntu
    label: str                       # short, for prompts and tables: "Ubuntu"
    device_name: str                 # in instructions: "Ubuntu desktop"
    screen: tuple[int, int]          # the default screen size (width, height)
    path_style: PathStyle
    case_insensitive_paths: bool
    home: str
    writable_roots: tuple[str, ...]  # where set-up may put files (upload_file paths)
    transfer_folder: str             # where the built-in transfer task saves received files
    shell: str                       # what `Device.run` runs commands with: bash | cmd | sh
    desktop_user: str | None = None  # the user commands run as by default (None: the shell's own)
    text_codepage: str | None = None  # the 8-bit ("ANSI") code page of plain text that is neither UTF-8 nor marked
    #                                  by a byte order mark; None: such bytes are no text on this platform
    today_command: str = "date +%F"  # prints the device's local date (YYYY-MM-DD) on standard output
    # file-system conventions, read by the evaluators' file facts (`evaluators/file_facts.py`):
    file_facts: Literal["posix_shell", "windows_probe"] = "posix_shell"  # how they are read on the device
    hidden_by: Literal["dot_name", "attributes"] = "dot_name"  # what hides an entry from a folder's listing
    trash: str | None = None         # where a deleted file waits to be restored: a freedesktop.org trash folder
    #                                  (info/ and files/); Windows: the Recycle Bin folder of each drive
    trash_prefix: str | None = None  # a trash that keeps a deleted file in its own folder under a marked name:
    #                                  Android's MediaStore renames it <prefix><expiry>-<name> (`.trashed-`)
    user_roots: tuple[str, ...] = ()  # every place the user, or an agent in the device's shell, may keep files:
    #                                  where a file said to be deleted must not turn up under another name
    shell_files: tuple[str, ...] = ()  # names the desktop's own file manager writes into folders (Explorer's
    #                                  desktop.ini, Thumbs.db): folder checks pass over one only if it is such a file
    drive_root: str | None = None    # where the transfer drive shows as a drive letter (Windows: S:\); None: it
    #                                  is reached over HTTP only
    # a command line through the GUI alone (GUI solutions of built-in tasks, `gui_shell_steps`): the GUI steps that
    # put one on screen, ready, with the keyboard in it, and the line that titles its window SHELL_TITLE (None: no
    # such recipe is known for the platform)
    gui_shell_open: tuple[dict, ...] | None = None
    gui_shell_title: str | None = None
    # the role of a window's button on the desktop's taskbar, named by the window's title: the GUI way to bring a
    # window to the front (a click on the button of the window in front minimises it); None: no taskbar known.
    # `taskbar_marks_front`: the button of the window in front is checked (XFCE's tasklist; Wine's is drawn pushed,
    # with no state to read)
    taskbar_button_role: str | None = None
    taskbar_marks_front: bool = False
    # the desktop's web browser (a program `start_command` starts with a URL) and its file dialog: GUI solutions
    # reach the transfer drive's web page with it (`tasks/transfer.py`); None: no browser (Wine has none: its
    # Gecko is not packaged), and such a device reaches the drive from its command line
    browser: str | None = None
    file_dialog: FileDialog | None = None
    # a touch screen: a press held on it is a LONG_PRESS, a drag a SWIPE, it has system buttons (SYSTEM_BUTTON) and
    # no pointer to rest anywhere (the browser player's inputs, `player/inputs.py`)
    touch: bool = False
    # who the device is, the same on any host: its container's hostname (shown in a terminal's title and prompt, a
    # drive page's title), its time zone and locale (the `TZ`, `LANG` and `LC_ALL` it starts with; never the host's)
    hostname: str = "device"
    timezone: str = "Etc/UTC"
    locale: str = "C.UTF-8"

    @property
    def sep(self) -> str:
        return "\\" if self.path_style == "windows" else "/"

    def join(self, *parts: str) -> str:
        return (ntpath if self.path_style == "windows" else posixpath).join(*parts)

    def normalise(self, path: str) -> str:
        """A path in the form two paths of this platform can be compared in (case folded where paths are)."""
        mod = ntpath if self.path_style == "windows" else posixpath
        path = mod.normpath(path.replace("/", "\\") if self.path_style == "windows" else path)
        return path.lower() if self.case_insensitive_paths else path

    def is_absolute(self, path: str) -> bool:
        if self.path_style == "windows":
            return len(path) > 2 and path[1] == ":" and path[2] in "\\/"
        return path.startswith("/")

    def may_write(self, path: str) -> bool:
        """Whether set-up may put a file at `path` (absolute, no `..`, under a writable root)."""
        if not self.is_absolute(path) or ".." in path.replace("\\", "/").split("/"):
            return False
        norm = self.normalise(path)
        roots = [self.normalise(r).rstrip(self.sep) for r in self.writable_roots]
        return any(norm.rstrip(self.sep) == r or norm.startswith(r + self.sep) for r in roots)

    def mkdir_command(self, folder: str) -> str:
        if self.shell == "cmd":
            return f'if not exist "{folder}" mkdir "{folder}"'
        return f"mkdir -p '{folder}'"

    def drive_put_command(self, path: str, url: str, password: str) -> str:
        """A command that puts the file at `path` on the transfer drive at `url` (`http://transfer:5244/data/<name>`)
        with the device's own means: curl on Linux; on Windows a copy to the drive letter `S:`, which both Windows
        backends map to the drive (Wine has no curl.exe)."""
        if self.shell == "cmd":
            return f'copy /y "{path}" "{self.drive_path(url)}"'
        if self.name == "android":  # no curl or wget on Android: HTTP/1.0 through toybox's nc
            from jarvis_pytest.devices.android.http import put_command

            return put_command(path, url, password)
        return f"curl -fsS -H 'PW: {password}' -T '{path}' '{url}'"

    def drive_get_command(self, url: str, path: str, password: str) -> str:
        """A command that fetches the drive's file at `url` into `path` with the device's own means."""
        if self.shell == "cmd":
            return f'copy /y "{self.drive_path(url)}" "{path}"'
        if self.name == "android":  # see drive_put_command
            from jarvis_pytest.devices.android.http import get_command

            return get_command(url, path, password)
        return f"curl -fsS -H 'PW: {password}' -o '{path}' '{url}'"

    def gui_shell_steps(self, command: str, note: str) -> list[dict]:
        """GUI solution steps that run `command` in the platform's command line opened through the GUI: the window
        is titled first, the command typed with `&& exit`, and its window must go within a minute — it stays, with
        the error on screen, where the command failed. Empty where the platform has no such recipe."""
        if self.gui_shell_open is None or self.gui_shell_title is None:
            return []
        window = {"window": SHELL_TITLE}
        return [*(dict(step, platform=self.name) for step in self.gui_shell_open),
                {"type": "TYPING", "text": self.gui_shell_title + "\n", "platform": self.name},
                {"type": "WAIT_FOR", "target": window, "timeout": 20, "platform": self.name},
                {"type": "TYPING", "text": f"{command} && exit\n", "platform": self.name, "note": note},
                {"type": "WAIT_FOR", "target": window, "gone": True, "timeout": 60, "platform": self.name,
                 "note": "the command line closes only if the command succeeded"}]

    def start_command(self, app: str | None, args: Sequence[str] = ()) -> str:
        """A command line that starts `app` with `args` (without `app`: opens the file `args[0]` with its default
        program) and returns at once, the program left running after the command line closes."""
        if self.shell == "cmd":
            from jarvis_pytest.devices.windows.server.programs import KNOWN_PROGRAMS

            program = KNOWN_PROGRAMS.get((app or "").lower().removesuffix(".exe"))  # not on PATH: `start` misses it
            return " ".join(['start ""', *([f'"{program}"' if program else app] if app else []),
                             *(f'"{a}"' for a in args)])
        words = [app, *args] if app else ["exo-open", *args]
        return f"setsid -f {shlex.join(words)} >/dev/null 2>&1"

    def drive_path(self, url: str) -> str:
        """Where a drive URL's file is on this device's drive letter (Windows: `S:\\data\\name`)."""
        if "://" not in url:
            return url
        return (self.drive_root or "S:\\") + url.split("/", 3)[3].replace("/", "\\")


PLATFORMS: dict[str, PlatformSpec] = {
    "android": PlatformSpec(
        name="android", label="Android", device_name="Android phone", screen=(1080, 2400), path_style="posix",
        case_insensitive_paths=False, home="/sdcard", writable_roots=("/sdcard", "/data/local/tmp"),
        transfer_folder="/sdcard/Download/transfer", shell="sh",
        trash_prefix=".trashed-", user_roots=("/sdcard", "/data/local/tmp"), touch=True, hostname="android-phone"),
    "windows": PlatformSpec(
        name="windows", label="Windows", device_name="Windows PC", screen=(1920, 1080), path_style="windows",
        case_insensitive_paths=True, home="C:\\Users\\user", writable_roots=("C:\\Users\\user", "C:\\temp", "S:\\"),
        transfer_folder="C:\\Users\\user\\Downloads\\transfer", drive_root="S:\\", shell="cmd",
        text_codepage="cp1252", hostname="windows-pc",
        file_facts="windows_probe", hidden_by="attributes", trash="$Recycle.Bin",
        shell_files=("desktop.ini", "thumbs.db"), user_roots=("C:\\Users", "C:\\temp", "S:\\"),
        # Wine's desktop: its taskbar's Start button, bottom left, opens a menu whose last item is Run...; win+r does
        # nothing there. The console's title is set by cmd's `title` once the command succeeded.
        gui_shell_open=({"type": "CLICK", "x": 28, "y": 1070, "note": "the taskbar's Start button"},
                        {"type": "CLICK", "x": 40, "y": 1050, "note": "Start > Run..."},
                        {"type": "WAIT_FOR", "target": {"window": "Run", "control": {"class": "Edit"}}},
                        {"type": "HOTKEY", "keys": ["end"], "note": "the box keeps the last command run"},
                        {"type": "HOTKEY", "keys": ["shift", "home"], "note": "all of it selected: typing replaces it"},
                        {"type": "TYPING", "text": "cmd.exe\n"},
                        {"type": "WAIT_FOR", "target": {"window": "\\cmd.exe"}, "timeout": 30}),
        gui_shell_title=f"title {SHELL_TITLE}", taskbar_button_role="push button",
        # the device's Python writes the date to a file that cmd's own `type` prints: under Wine the output of a
        # program the control server's cmd starts never reaches the server, that of cmd's built-ins does
        today_command=('"C:\\jarvis\\python\\pythonw.exe" -I -c "import datetime,os; open(os.path.join(os.environ['
                       "'TEMP'],'jarvis-today.txt'),'w').write(datetime.date.today().isoformat())\" && type "
                       '"%TEMP%\\jarvis-today.txt" && del "%TEMP%\\jarvis-today.txt"')),
    "ubuntu": PlatformSpec(
        name="ubuntu", label="Ubuntu", device_name="Ubuntu desktop", screen=(1920, 1080), path_style="posix",
        case_insensitive_paths=False, home="/home/user", writable_roots=("/home/user", "/tmp"),
        transfer_folder="/tmp/transfer", shell="bash", desktop_user="user", hostname="ubuntu-desktop",
        trash="/home/user/.local/share/Trash", user_roots=("/home/user", "/tmp", "/var/tmp", "/dev/shm"),
        # XFCE's keyboard shortcut for the terminal; its window shows before its shell's prompt and before it has the
        # keyboard: the prompt awaited, the terminal clicked. (Its text in AT-SPI lags behind the screen: the window
        # title tells the state.) The prompt would set the title again: it is replaced by one that does not.
        gui_shell_open=({"type": "HOTKEY", "keys": ["ctrl", "alt", "t"], "note": "XFCE: open a terminal"},
                        {"type": "WAIT_FOR", "timeout": 30, "note": "its shell's prompt",
                         "target": {"window": "Terminal - ", "control": {"role": "terminal", "text": "*$"}}},
                        {"type": "CLICK", "target": {"window": "Terminal - ", "control": {"role": "terminal"}}}),
        gui_shell_title=f"PS1='$ '; printf '\\033]0;{SHELL_TITLE}\\007'", taskbar_button_role="toggle button",
        taskbar_marks_front=True, browser="chromium",
        file_dialog=FileDialog(type_path=("ctrl", "l"), open=("alt", "o"), save=("alt", "s"))),
}
PLATFORM_NAMES: tuple[str, ...] = tuple(PLATFORMS)


def spec(platform: str) -> PlatformSpec:
    """The facts of `platform`; a ConfigError naming the known platforms otherwise."""
    try:
        return PLATFORMS[platform]
    except KeyError:
        raise ConfigError(f"unknown platform {platform!r}", field="platform",
                          fix=f"use one of {', '.join(PLATFORMS)}") from None
