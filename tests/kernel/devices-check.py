#!/usr/bin/python3
"""In the kernel lane: `gonioctl devices --json` lists what the guest's test drivers
created: both vivid nodes with their formats (YUYV among them, with sizes) and controls
(Brightness), the gpio-sim chip "gonio-gpio" (init) with its named lines, and at least one
vimc camera through libcamera with its formats. The human output names them too, and
neither output has anything on stderr (libcamera's log is silenced). Usage:
devices-check.py GONIOCTL"""
import json
import subprocess
import sys


def gonioctl(*args):
    done = subprocess.run([sys.argv[1], *args], check=True, capture_output=True, text=True)
    assert done.stderr == "", f"stderr not quiet (libcamera's log?): {done.stderr[:300]}"
    return done.stdout


def check(found):
    vivid = [d for d in found["v4l2"] if "vivid" in d["name"]]
    sims = [d for d in found["gpio"] if d["driver"] == "gpio-sim"]
    cams = [c for c in found["libcamera"] if "vimc" in c["id"]]
    print(f"devices: {len(vivid)} vivid nodes, {len(sims)} gpio-sim chips, "
          f"{len(cams)} vimc cameras, {len(found['usb'])} usb devices")
    assert len(vivid) >= 2, "two vivid nodes"
    for node in vivid:
        yuyv = [f for f in node["formats"] if f["fourcc"] == "YUYV"]
        assert yuyv and (yuyv[0]["sizes"] or "range" in yuyv[0]), f"{node['path']}: YUYV sizes"
        bright = [c for c in node["controls"] if c["name"] == "Brightness"]
        assert bright and bright[0]["type"] == "integer", f"{node['path']}: Brightness"
        assert bright[0]["min"] <= bright[0]["default"] <= bright[0]["max"]
    chip = [d for d in sims if d.get("label") == "gonio-gpio"]
    assert chip, "gpio-sim chip gonio-gpio"
    names = [line["name"] for line in chip[0]["lines"]]
    assert names[:3] == ["step", "dir", "enable"] and "limit_max" in names, names
    assert all(line["direction"] in ("input", "output") for line in chip[0]["lines"])
    assert cams, f"a vimc camera ({found.get('libcamera_error', 'no error')})"
    assert all(c["formats"] and c["formats"][0]["sizes"] for c in cams), "vimc formats"


def check_text(text, found):
    for word in ("YUYV", "Brightness", "gonio-gpio", "limit_max", found["libcamera"][0]["id"]):
        assert word in text, f"human output lacks {word}"


out = ""
try:
    out = gonioctl("--json", "devices")
    check(json.loads(out))
    check_text(gonioctl("devices"), json.loads(out))
except AssertionError as e:
    print(out, file=sys.stderr)
    print(f"devices-check: {e}", file=sys.stderr)
    sys.exit(1)
