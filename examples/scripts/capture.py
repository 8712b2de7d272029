#!/usr/bin/env python3
"""capture.py - a lab script with gonio's Python client (docs/python.md): homes the rig,
captures a turntable sweep with each lamp alone into a new dataset, shows a refused move,
then runs a session over the same object into that dataset, following its progress, and
checks the dataset.

On the simulated rig (docs/python.md, "Example"), from the source tree:

    PYTHONPATH=python GONIO_SOCKET=$SOCK python3 examples/scripts/capture.py [DATASET]

It finds goniod as gonioctl does ($GONIO_SOCKET, else $XDG_RUNTIME_DIR/gonio/goniod.sock, else
/run/gonio/goniod.sock). Exits 0 when done, 1 with the error on stderr."""

import sys
import time

import gonio

SESSION = """\
name: sweep
dataset: {dataset}
sweep:
  turntable: {{ from: 0, to: 270, step: 90 }}
cameras: [{camera}]
lamps: all
"""


def role(status, name):
    """The name of the axis of role name ("turntable", "light_arm", "camera_arm")."""
    return next(a["name"] for a in status["axes"] if a.get("role") == name)


def progress(st):
    """Prints a session's progress (run_session's on_progress)."""
    print(f"  session {st.get('name')}: {st['state']} {st.get('captured', 0)}/"
          f"{st.get('planned', 0)}", flush=True)


def refused_move(rig, status):
    """Moves the first axis with soft limits past its upper limit: goniod refuses it."""
    axis = next(a for a in status["axes"] if not a["continuous"])
    try:
        rig.move(axis["name"], axis["max"] + 10)
    except gonio.GonioError as e:
        if e.code != gonio.E_RANGE:
            raise
        print(f"refused: {e.message}")


def main():
    dataset = sys.argv[1] if len(sys.argv) > 1 else time.strftime("scripted-%Y%m%d-%H%M%S")
    with gonio.Client() as rig:
        info = rig.server
        print(f"connected to {info['server']} {info['version']}, rig {info['rig']}")
        st = rig.status()
        turntable = role(st, "turntable")
        rig.home()
        rig.dataset_open(dataset, create=True)
        for angle in (0, 120, 240):
            for lamp in st["lamps"]:
                for cap in rig.capture_at({turntable: angle}, lamps=[lamp["name"]]):
                    print(f"  {cap['file']}  turntable {cap['turntable']:.1f}")
        rig.set_lamps([])
        refused_move(rig, st)
        session = SESSION.format(dataset=dataset, camera=st["cameras"][0]["name"])
        plan = rig.session_plan("sweep.yaml", session)
        print(f"session sweep: {plan['captures']} captures, about {plan['estimate_s']:.0f} s")
        rig.run_session("sweep.yaml", session, on_progress=progress)
        check = rig.dataset_check(dataset)
        print(f"{check['count']} captures, {len(check['problems'])} problems")
        print(f"dataset: {check['path']}")


if __name__ == "__main__":
    try:
        main()
    except gonio.GonioError as e:
        print(f"capture.py: {e}", file=sys.stderr)
        sys.exit(1)
