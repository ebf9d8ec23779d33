"""Programs Windows (and Wine) has but not on PATH: where they are, for the server's `launch` and for a command line
typed through the GUI (`platforms.PlatformSpec.start_command`). Pure data: imported on the host too."""

KNOWN_PROGRAMS = {  # found through App Paths on real Windows; Wine registers none of them
    "wordpad": r"%ProgramFiles%\Windows NT\Accessories\wordpad.exe",
    "iexplore": r"%ProgramFiles%\Internet Explorer\iexplore.exe",
    "msedge": r"%ProgramFiles(x86)%\Microsoft\Edge\Application\msedge.exe",
}
