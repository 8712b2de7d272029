#!/usr/bin/env python3
"""test-dashboard.py GONIOD GONIO_SIM SOURCE_ROOT [SCREENSHOT.png] - goniod's dashboard
(docs/goniod.md, "Dashboard") in headless Chromium (tests/appearance/browser.py), on
gonio-sim (tests/python/harness.py): signed in by /?token=T, the page shows the rig's state
and its axes, follows a short session's progress from the daemon's event stream (running
with captures made, then ended done with every planned capture), and each camera's <img> has decoded a live
picture of the camera's size. The page is screenshot (to SCREENSHOT.png when given) and
must not be blank. Exits 77 (skipped) when Chromium is not installed."""
import base64
import os
import socket
import sys
import threading

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, '..', 'python'))
sys.path.insert(0, os.path.join(HERE, '..', 'appearance'))
import browser  # noqa: E402
import gonio  # noqa: E402
from harness import Rig, check  # noqa: E402

TOKEN = 'a-dashboard-token-of-some-length'
SESSION = """\
name: web1
dataset: webds
sweep:
  turntable: { from: 0, to: 270, step: 90 }
cameras: [cam0, cam1]
lamps: [lamp0]
skip_occluded: false
skip_glare: false
"""


def free_port():
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def main():
    goniod, gonio_sim = sys.argv[1], sys.argv[2]
    shot = sys.argv[4] if len(sys.argv) > 4 else None
    if not browser.CHROMIUM:
        print('chromium is not installed: skipped', file=sys.stderr)
        sys.exit(77)
    rig = Rig(goniod, gonio_sim, time_scale=20)
    port = free_port()
    with open(os.path.join(rig.dir, 'token'), 'w') as f:
        f.write(TOKEN + '\n')
    rig.env.update(GONIO_LISTEN_HTTP=f'127.0.0.1:{port}',
                   GONIO_TOKEN_FILE=os.path.join(rig.dir, 'token'))
    started = {}  # Chromium starts while gonio-sim and goniod do
    t = threading.Thread(target=lambda: started.update(b=browser.Browser(width=1100, height=900)))
    t.start()
    with rig:
        t.join()
        check('b' in started, 'chromium started')
        with started['b'] as b:
            follow(rig, b, port, shot)


def follow(rig, b, port, shot):
    """Signs in, runs the session and checks what the page shows."""
    c = gonio.Client(rig.sock)
    c.home()
    b.open(f'http://127.0.0.1:{port}/?token={TOKEN}')
    b.wait('window.gonio && gonio.updates > 0 && gonio.status.homed', timeout=10)
    check(b.eval("document.getElementById('state').textContent") == 'idle', 'state shown')
    rows = b.eval("[...document.querySelectorAll('#axes tbody tr')].map(r => r.cells[0].textContent)")
    check(rows == [a['name'] for a in c.status()['axes']], 'axes shown', rows)
    path = os.path.join(rig.dir, 's.yaml')
    with open(path, 'w') as f:
        f.write(SESSION)
    planned = c.session_plan(path)['captures']
    c.session_run(path)
    b.wait("gonio.session.state === 'running' && gonio.session.captured > 0 && "
           "document.getElementById('progress').value > 0", timeout=10)
    mid = b.eval("document.getElementById('progress-text').textContent")
    check(f'/ {planned} captured' in mid, 'progress shown', mid)
    b.wait("gonio.session.state === 'none' && gonio.session.ended === 'done'", timeout=15)
    end = b.eval("[document.getElementById('session').textContent, "
                 "document.getElementById('progress').value]")
    check(end == ['session web1 (webds): ended, done', planned], 'the end shown', end)
    sizes = b.wait("(() => { const i = [...document.querySelectorAll('#cameras img')];"
                   " return i.length === 2 && i.every(x => x.complete && x.naturalWidth > 0)"
                   " && i.map(x => [x.alt, x.naturalWidth, x.naturalHeight]); })()",
                   timeout=10)
    cams = {x['name']: (x['width'], x['height']) for x in c.status()['cameras']}
    check(all(tuple(s[1:]) == (w // -(-w // 320), h // -(-w // 320))
              for s in sizes for w, h in [cams[s[0]]]), 'pictures of the camera size', sizes)
    png = base64.b64decode(b.call('Page.captureScreenshot', session=True, format='png')['data'])
    path = shot or os.path.join(rig.dir, 'dashboard.png')
    with open(path, 'wb') as f:
        f.write(png)
    w, h, ch, px = browser.read_png(path)
    check(len(set(px[i] for i in range(0, len(px), 97))) > 20, 'the screenshot is not blank')
    check(not b.errors(), 'no console errors', b.errors())
    c.close()
    print('dashboard ok: session of', planned, 'captures followed; pictures', sizes,
          'screenshot', path if shot else '(removed with the temp dir)')


if __name__ == '__main__':
    main()
