#!/usr/bin/python3
"""In the kernel lane: `gonioctl devices --json` lists what the guest's test drivers
created: both vivid nodes, the gpio-sim chips (named by their driver). Usage:
devices-check.py GONIOCTL"""
import json
import subprocess
import sys

out = subprocess.run([sys.argv[1], "--json", "devices"], check=True, capture_output=True,
                     text=True).stdout
found = json.loads(out)
vivid = [d for d in found["v4l2"] if "vivid" in d["name"]]
sims = [d for d in found["gpio"] if d["driver"] == "gpio-sim"]
print(f"devices: {len(vivid)} vivid nodes, {len(sims)} gpio-sim chips, "
      f"{len(found['usb'])} usb devices")
if len(vivid) < 2 or len(sims) < 1:
    print(out, file=sys.stderr)
    sys.exit(1)
