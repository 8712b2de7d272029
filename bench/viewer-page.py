#!/usr/bin/env python3
"""viewer-page.py GONIOCTL MODEL WxH - bench/viewer's browser half: gonioctl model view MODEL
served on loopback, the page opened at WxH in headless Chromium (software GL), and printed as
one JSON line: the frames per second it reaches while the light moves, and the bytes it
downloaded before its first relit frame (the Resource Timing sizes of the page, its script and
its data, as the first frame was drawn)."""
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'tests',
                                'appearance'))
import browser  # noqa: E402

FRAMES = 10


def main():
    gonioctl, model, size = sys.argv[1:4]
    w, h = (int(v) for v in size.split('x'))
    srv = subprocess.Popen([gonioctl, 'model', 'view', model], stdout=subprocess.PIPE, text=True)
    try:
        line = srv.stdout.readline()
        url = line[line.index('http://'):].split()[0]
        with browser.Browser(w + 40, h + 200) as b:
            b.open(url + f'?size={size}')
            b.wait('gonio.state === "complete" || gonio.state === "error"', 300)
            if b.eval('gonio.state') != 'complete':
                sys.exit('viewer-page: ' + str(b.eval('gonio.error')))
            fps = b.eval(f'gonio.fps({FRAMES})', timeout=600)
            first = b.eval('gonio.firstFrameBytes')
            print(json.dumps({'fps': round(fps, 2), 'first_frame_bytes': first,
                              'errors': b.errors()}))
    finally:
        srv.send_signal(2)
        srv.wait(timeout=20)


main()
