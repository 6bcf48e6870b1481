"""``rtusniff wireshark setup``: Wireshark set up once to read rtusniff's pcaps and to capture live.

Two things are written into the user's own Wireshark folders, never over a file rtusniff did
not write:

* the configuration profile ``rtusniff`` (``wireshark -C rtusniff``): the preference that makes
  Wireshark's Modbus RTU dissector read UDP port 502 (``export --pcap``'s encapsulation, by which
  it tells every query from its response), CRC checking on, and the DLT_USER entry for pcaps of
  link type 147 (``--pcap-link user``, and pcaps written by earlier versions);
* an extcap launcher (``rtusniff-extcap``, ``.bat`` on Windows) in the personal extcap folder,
  which runs ``rtusniff wireshark extcap`` with this Python: Wireshark then lists each serial
  port as a capture interface (:mod:`sniffer.extcap`).

Wireshark's folders are asked of ``tshark -G folders`` where tshark is found; otherwise they are
Wireshark's defaults for the platform (the personal extcap folder moved in Wireshark 4.1).
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from sniffer.errors import ErrorKind, RtuSniffError

PROFILE = "rtusniff"
#: The first line of every file rtusniff writes: what it may replace.
MARK = "# Written by 'rtusniff wireshark setup'; it rewrites this file, so edit a copy."
#: Link type 147 (DLT_USER0) read as Modbus RTU: Wireshark's ``user_dlts`` table, one row.
USER_DLT_ROW = '"User 0 (DLT=147)","mbrtu","0","","0",""'
PREFERENCES = ("mbrtu.udp.port: 502", "mbrtu.crc_verification: TRUE")
LAUNCHER = "rtusniff-extcap"
#: Where Wireshark is installed when it is not on the PATH.
_TSHARK_PLACES = ("/Applications/Wireshark.app/Contents/MacOS/tshark", r"C:\Program Files\Wireshark\tshark.exe")


@dataclass(frozen=True)
class Folders:
    """The user's Wireshark folders: its configuration, and where it looks for extcaps."""

    configuration: Path
    extcap: Path
    #: How they were found: ``tshark -G folders``, or the platform's defaults.
    found_by: str


def tshark_program() -> str | None:
    found = shutil.which("tshark")
    return found or next((place for place in _TSHARK_PLACES if Path(place).is_file()), None)


def wireshark_folders(tshark: str | None) -> Folders:
    """The folders as Wireshark reports them, or its defaults (see the module docstring)."""
    if tshark is not None:
        try:
            listed = subprocess.run([tshark, "-G", "folders"], capture_output=True, text=True, timeout=30,
                                    check=True).stdout
            version = subprocess.run([tshark, "--version"], capture_output=True, text=True, timeout=30,
                                     check=True).stdout
        except (OSError, subprocess.SubprocessError):
            listed = version = ""
        folders = dict(re.findall(r"^([^:\n]+):\s*(.+?)\s*$", listed, re.MULTILINE))
        if "Personal configuration" in folders:
            configuration = Path(folders["Personal configuration"])
            extcap = folders.get("Personal Extcap path")
            return Folders(configuration, Path(extcap) if extcap else _personal_extcap(configuration, version),
                           f"{tshark} -G folders")
    return _default_folders()


def _personal_extcap(configuration: Path, version: str) -> Path:
    """Wireshark before 4.1 lists no personal extcap folder and looks in the configuration's."""
    match = re.search(r"Wireshark\)? (\d+)\.(\d+)", version)
    if match and (int(match[1]), int(match[2])) < (4, 1):
        return configuration / "extcap"
    return _default_folders().extcap


def _default_folders() -> Folders:
    if sys.platform == "win32":
        roaming = Path(os.environ.get("APPDATA", Path.home() / "AppData" / "Roaming")) / "Wireshark"
        return Folders(roaming, roaming / "extcap", "Wireshark's defaults for Windows")
    configuration = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config") / "wireshark"
    return Folders(configuration, Path.home() / ".local" / "lib" / "wireshark" / "extcap",
                   "Wireshark's defaults (4.1 or later)")


def profile_files() -> dict[str, str]:
    """The profile's files by name, as written."""
    return {"preferences": "\n".join([MARK, *PREFERENCES]) + "\n", "user_dlts": f"{MARK}\n{USER_DLT_ROW}\n"}


def launcher(ports: list[str]) -> tuple[str, str]:
    """The extcap launcher's file name and text: this Python running ``rtusniff wireshark extcap``,
    with the ``ports`` named at setup besides those the system lists."""
    extra = [arg for port in ports for arg in ("--port", port)]
    if sys.platform == "win32":
        words = " ".join(f'"{word}"' for word in [sys.executable, "-m", "sniffer", "wireshark", "extcap", *extra])
        return f"{LAUNCHER}.bat", f"@echo off\r\nrem {MARK[2:]}\r\n{words} %*\r\n"
    words = shlex.join([sys.executable, "-m", "sniffer", "wireshark", "extcap", *extra])
    return LAUNCHER, f"#!/bin/sh\n{MARK}\nexec {words} \"$@\"\n"


def install(folders: Folders, ports: list[str]) -> list[tuple[Path, str]]:
    """Writes the profile and the launcher; returns each file with what became of it (written,
    unchanged). Refuses, before writing anything, a file of the same name that rtusniff did not write."""
    name, text = launcher(ports)
    planned = [(folders.configuration / "profiles" / PROFILE / file, body) for file, body in profile_files().items()]
    planned.append((folders.extcap / name, text))
    for path, _ in planned:
        _refuse_foreign(path)
    done = []
    for path, body in planned:
        if path.is_file() and path.read_text(encoding="utf-8") == body:
            done.append((path, "unchanged"))
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(f".{path.name}.partial")
        partial.write_text(body, encoding="utf-8", newline="")
        if path.name == LAUNCHER:
            partial.chmod(0o755)
        os.replace(partial, path)
        done.append((path, "written"))
    return done


def _refuse_foreign(path: Path) -> None:
    if not os.path.lexists(path):
        return
    try:
        ours = path.is_file() and not path.is_symlink() and MARK[2:] in path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        ours = False
    if not ours:
        raise RtuSniffError(ErrorKind.OUTPUT_FAILED, "exists and was not written by rtusniff; left as it is (move "
                            "it away, or name other folders with --config-dir / --extcap-dir)", path=str(path))
