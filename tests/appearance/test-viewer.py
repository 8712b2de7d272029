#!/usr/bin/env python3
"""test-viewer.py CASE - the relighting viewer (gonioctl model view / model export --web) in
headless Chromium (tests/appearance/browser.py), on the model viewer-fixture writes:

  match    at three (light, view) pairs (point light per pixel, point light per object, an
           environment map) the page's picture equals gonioctl model render's to 40 dB inside
           the object, with the same object pixels; no console errors; the first frame comes
           before every view is loaded; the frame rate of software GL is printed
  drag     dragging with shift moves the light (the picture changes, the object does not),
           dragging alone turns the view (the object moves)
  offline  the exported folder opened from file:// draws the same picture, no server
  bad      an export into a non-empty folder, a truncated or newer model, a damaged data file,
           a newer page format, a browser without WebGL2: a clear message each
  brdf     with a BRDF model beside the SH model: the page's environment frame with it
           against ap_env_render's of the same camera (viewer-fixture render) to 40 dB over the
           object and over the ground, away from their outlines; the model toggle; a damaged
           BRDF data file named by the page, a damaged BRDF model named by the export

Exits 77 (skipped) when Chromium is not installed. Environment: GONIOCTL, VIEWER_FIXTURE."""
import math
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import browser  # noqa: E402

GONIOCTL = os.environ['GONIOCTL']
SIZE = (96, 72)
MIN_DB = 50.0  # the issue asks 40 dB; the page agrees to 54-62 dB, so 50 catches subtle slips
READY = 'gonio.state === "complete" || gonio.state === "error"'


def check(cond, what):
    if not cond:
        print('check failed:', what, file=sys.stderr)
        sys.exit(1)


def gonioctl(*args, ok=True):
    r = subprocess.run([GONIOCTL] + list(args), capture_output=True, text=True, timeout=120)
    if ok and r.returncode != 0:
        print(r.stdout, r.stderr, file=sys.stderr)
        check(False, 'gonioctl ' + ' '.join(args))
    return r


class Fixture:
    """The fitted model in a temporary folder (with a BRDF model beside it: brdf), an
    environment map beside it."""

    def __init__(self, brdf=False):
        self.dir = tempfile.mkdtemp(prefix='gonio-viewer-')
        subprocess.run([os.environ['VIEWER_FIXTURE'], self.dir] + (['brdf'] if brdf else []),
                       check=True, timeout=120)
        self.model = os.path.join(self.dir, 'ds', 'models', 'default')
        self.env = os.path.join(self.dir, 'sky.pfm')
        w, h = 16, 8  # a bright patch high on one side, a dim sky, a darker ground
        px = []
        for y in range(h):
            for x in range(w):
                v = 2.0 if (y == 1 and 3 <= x <= 5) else 0.08 if y < h // 2 else 0.02
                px += [v, v * 0.9, v * 0.8]
        with open(self.env, 'wb') as f:
            f.write(f'PF\n{w} {h}\n-1.0\n'.encode() + struct.pack(f'<{len(px)}f', *px))

    def close(self):
        shutil.rmtree(self.dir, ignore_errors=True)


class Server:
    """gonioctl model view MODEL on a free loopback port."""

    def __init__(self, model, *extra):
        self.proc = subprocess.Popen([GONIOCTL, 'model', 'view', model] + list(extra),
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        line = self.proc.stdout.readline()
        check('http://127.0.0.1:' in line, 'model view prints its address: ' + line)
        self.url = line[line.index('http://'):].split()[0]

    def close(self):
        self.proc.send_signal(2)  # SIGINT, as Ctrl-C
        check(self.proc.wait(timeout=20) == 0, 'model view ends cleanly on SIGINT')


def cpu_render(fx, args):
    out = os.path.join(fx.dir, 'cpu.png')
    gonioctl('model', 'render', fx.model, '--size', '%dx%d' % SIZE, '-o', out, *args)
    return browser.read_png(out)


def compare(page, cpu):
    """PSNR (dB) over the page's object pixels away from its silhouette, and the share of
    the renderer's lit pixels the page leaves out."""
    w, h, px = page
    cw, ch, nc, ref = cpu
    check((w, h) == (cw, ch) and nc == 3, 'sizes agree')

    def inside(x, y):
        return 0 <= x < w and 0 <= y < h and px[4 * (y * w + x) + 3] == 255
    sse, n, lit, missing = 0.0, 0, 0, 0
    for y in range(h):
        for x in range(w):
            i = y * w + x
            if sum(ref[3 * i:3 * i + 3]) > 0:
                lit += 1
                missing += px[4 * i + 3] != 255
            if all(inside(x + dx, y + dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)):
                for c in range(3):
                    sse += (px[4 * i + c] - ref[3 * i + c]) ** 2
                    n += 1
    check(n > 3 * 1000, f'enough object pixels ({n // 3})')
    return 10 * math.log10(255.0 ** 2 * n / max(sse, 1e-9)), missing / max(lit, 1)


PAIRS = [  # (name, page query, gonioctl model render options)
    ('point light, per pixel', 'view=20,25&light=300,-250,350',
     ['--view', '20,25', '--light', '300,-250,350']),
    ('point light, per object', 'view=-70,30&light=-200,300,300&mode=object',
     ['--view', '-70,30', '--light', '-200,300,300', '--mode', 'object']),
    ('environment map, per pixel', 'view=130,20&env=sky.pfm&gain=4',
     ['--view', '130,20', '--envmap', None, '--gain', '4']),
]


def open_page(b, url):
    b.open(url)
    b.wait(READY, 90)
    check(b.eval('gonio.state') == 'complete', 'page loads: %s' % b.eval('gonio.error'))


def test_match(fx):
    srv = Server(fx.model, '--envmap', fx.env)
    try:
        with browser.Browser() as b:
            for name, query, args in PAIRS:
                open_page(b, srv.url + '?size=%dx%d&' % SIZE + query)
                args = [fx.env if a is None else a for a in args]
                db, missing = compare(b.pixels(), cpu_render(fx, args))
                print(f'{name}: {db:.2f} dB, {100 * missing:.2f}% of the object missing')
                check(db >= MIN_DB, f'{name}: {db:.2f} dB >= {MIN_DB}')
                check(missing <= 0.01, f'{name}: the same object pixels')
            first, total = b.eval('[gonio.firstFrameBytes, gonio.total]')
            check(0 < first < total, f'a first frame at {first} of {total} bytes')
            fps = b.eval('gonio.fps(5)')
            print(f'software GL: {fps:.1f} frames per second at {SIZE[0]}x{SIZE[1]}')
            check(fps > 0, 'frames drawn')
            check(not b.errors(), 'no console errors: %s' % b.errors())
    finally:
        srv.close()


def mean_diff(a, b):
    return sum(abs(x - y) for x, y in zip(a[2], b[2])) / len(a[2])


def alpha(p):
    return bytes(p[2][3::4])


def test_drag(fx):
    srv = Server(fx.model)
    try:
        with browser.Browser() as b:
            open_page(b, srv.url + '?size=320x240')
            box = b.eval('(() => { const r = document.getElementById("view")'
                         '.getBoundingClientRect(); return [r.left, r.top]; })()')
            x, y = box[0] + 160, box[1] + 120
            before = b.pixels()
            b.drag(x, y, x + 60, y - 30, shift=True)
            lit = b.pixels()
            print('light dragged: mean change %.2f' % mean_diff(before, lit))
            check(mean_diff(before, lit) > 0.5, 'dragging the light changes the picture')
            check(alpha(before) == alpha(lit), 'dragging the light leaves the object in place')
            b.drag(x, y, x + 80, y, shift=False)
            turned = b.pixels()
            check(alpha(turned) != alpha(lit) or mean_diff(lit, turned) > 0.5,
                  'dragging turns the view')
            check(not b.errors(), 'no console errors: %s' % b.errors())
    finally:
        srv.close()


def test_offline(fx):
    out = os.path.join(fx.dir, 'web')
    r = gonioctl('model', 'export', '--web', out, fx.model)
    check('index.html' in r.stdout, 'export names the page')
    srv = Server(fx.model)
    try:
        with browser.Browser() as b:
            q = '?size=%dx%d&view=40,30&light=250,250,300' % SIZE
            open_page(b, 'file://' + out + '/index.html' + q)
            offline = b.pixels()
            check(not b.errors(), 'no console errors from file://: %s' % b.errors())
            open_page(b, srv.url + q)
            check(b.pixels() == offline, 'the same picture from file:// and from the server')
    finally:
        srv.close()


def page_error(url, flags=()):
    with browser.Browser(extra_flags=flags) as b:
        b.open(url)
        b.wait(READY, 60)
        check(b.eval('gonio.state') == 'error', 'the page reports an error')
        msg = b.eval('document.getElementById("message").textContent')
        print('page says:', msg)
        return msg


def test_bad(fx):
    # an export into a non-empty folder: refused, the folder untouched
    busy = os.path.join(fx.dir, 'busy')
    os.mkdir(busy)
    open(os.path.join(busy, 'keep'), 'w').write('mine')
    r = gonioctl('model', 'export', '--web', busy, fx.model, ok=False)
    check(r.returncode != 0 and 'not an empty folder' in r.stderr, 'non-empty: ' + r.stderr)
    check(os.listdir(busy) == ['keep'], 'the folder untouched')
    check(not [d for d in os.listdir(fx.dir) if d.startswith('.busy')], 'no temporary left')
    # a truncated model and a newer one: refused by export and view alike
    mj = os.path.join(fx.model, 'model.json')
    good = open(mj).read()
    for text, words in ((good[:len(good) // 2], 'model.json'),
                        (good.replace('gonio-appearance 1', 'gonio-appearance 9'), 'format')):
        open(mj, 'w').write(text)
        for args in (['export', '--web', os.path.join(fx.dir, 'w2')], ['view']):
            r = gonioctl('model', *args, fx.model, ok=False)
            print('gonioctl model %s: exit %d: %s' % (args[0], r.returncode, r.stderr.strip()))
            check(r.returncode == 6 and words in r.stderr, 'a clear error')
        check(not os.path.exists(os.path.join(fx.dir, 'w2')), 'nothing written')
    open(mj, 'w').write(good)
    # a damaged data file and a page of a newer format: the page says so
    out = os.path.join(fx.dir, 'web')
    gonioctl('model', 'export', '--web', out, fx.model)
    url = 'file://' + out + '/index.html'
    mesh = os.path.join(out, 'data', 'mesh.js')
    text = open(mesh).read()
    open(mesh, 'w').write(text[:len(text) // 2] + '");\n')
    check('mesh' in page_error(url), 'a damaged chunk is named')
    open(mesh, 'w').write(text)
    man = os.path.join(out, 'data', 'model.js')
    text = open(man).read()
    open(man, 'w').write(text.replace('gonio-web 1', 'gonio-web 7'))
    check('gonio-web 7' in page_error(url), 'a newer page format is named')
    open(man, 'w').write(text)
    check('WebGL2' in page_error(url, ['--disable-webgl2']), 'no WebGL2 is said')


def sun_env(path, w=64, h=32):
    """A lat-long PFM: a sky brighter at the zenith, a dark ground, a sun of 0.2 rad."""
    s = (math.cos(0.7) * math.cos(2.2), math.cos(0.7) * math.sin(2.2), math.sin(0.7))
    rows = []
    for y in range(h):  # top row first
        th = math.pi * (y + 0.5) / h
        row = []
        for x in range(w):
            ph = 2 * math.pi * (x + 0.5) / w
            d = (math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th))
            sun = 4.0 if sum(a * b for a, b in zip(d, s)) > math.cos(0.2) else 0.0
            sky = [0.12, 0.15, 0.22] if d[2] > 0 else [0.04, 0.035, 0.03]
            row += [v * (0.6 + 0.6 * max(d[2], 0)) + sun for v in sky]
        rows.append(row)
    with open(path, 'wb') as f:
        f.write(f'PF\n{w} {h}\n-1.0\n'.encode())
        for row in reversed(rows):  # PFM: bottom row first
            f.write(struct.pack(f'<{len(row)}f', *row))


def read_pnm(path):
    with open(path, 'rb') as f:
        magic, size, _, data = f.read().split(b'\n', 3)
    w, h = map(int, size.split())
    return w, h, data


def env_reference(fx, cam, env, spheres, gain):
    """ap_env_render's frame for the page's camera: (w, h, RGB bytes, mask bytes)."""
    out = os.path.join(fx.dir, 'ref')
    args = [str(v) for v in [env, spheres, gain, cam['width'], cam['height'], cam['fx'],
                             cam['fy'], cam['cx'], cam['cy']] + cam['R'] + cam['t']]
    subprocess.run([os.environ['VIEWER_FIXTURE'], 'render', fx.dir] + args + [out], check=True,
                   timeout=60)
    w, h, rgb = read_pnm(out + '.ppm')
    return w, h, rgb, read_pnm(out + '.pgm')[2]


def env_psnr(page, ref, cls):
    """PSNR (dB, peak 255) of the page's RGB against the reference over the pixels of mask
    class cls (1 object, 2 ground) whose 8 neighbours are of that class too."""
    w, h, px = page
    _, _, rgb, mask = ref
    sse, n = 0.0, 0
    for y in range(1, h - 1):
        for x in range(1, w - 1):
            if any(mask[(y + dy) * w + x + dx] != cls for dx in (-1, 0, 1) for dy in (-1, 0, 1)):
                continue
            i = y * w + x
            sse += sum((px[4 * i + c] - rgb[3 * i + c]) ** 2 for c in range(3))
            n += 3
    check(n > 3 * 500, f'enough pixels of class {cls} ({n // 3})')
    return 10 * math.log10(255.0 ** 2 * n / max(sse, 1e-9))


def test_brdf(fx):
    env, spheres, gain = os.path.join(fx.dir, 'sun.pfm'), 16, 2
    sun_env(env)
    out = os.path.join(fx.dir, 'web')
    gonioctl('model', 'export', '--web', out, fx.model, '--envmap', env, '--spheres', str(spheres))
    url = 'file://' + out + '/index.html?size=%dx%d&view=130,20&env=sun.pfm&gain=%g' % (SIZE + (gain,))
    with browser.Browser() as b:
        open_page(b, url)
        page = b.pixels()
        ref = env_reference(fx, b.eval('gonio.camera()'), env, spheres, gain)
        for cls, what in ((1, 'object'), (2, 'ground')):
            db = env_psnr(page, ref, cls)
            print(f'BRDF environment frame, {what}: {db:.2f} dB against ap_env_render')
            check(db >= 40, f'{what}: {db:.2f} dB >= 40')
        b.eval('gonio.set({model: "sh"})')
        sh = b.pixels()
        check(mean_diff(sh, page) > 5, 'model=sh shows the SH model')
        b.eval('gonio.set({model: "brdf"})')
        check(b.pixels() == page, 'model=brdf shows the BRDF model again')
        first, total = b.eval('[gonio.firstFrameBytes, gonio.total]')
        check(0 < first < total, f'the BRDF frame first, at {first} of {total} bytes')
        print(f'software GL, BRDF model: {b.eval("gonio.fps(3)"):.1f} frames per second')
        check(not b.errors(), 'no console errors: %s' % b.errors())
    # a damaged BRDF data file: the page names it
    texels = os.path.join(out, 'data', 'brdf_texels.js')
    text = open(texels).read()
    open(texels, 'w').write(text[:len(text) // 2] + '");\n')
    check('brdf_texels' in page_error(url), 'a damaged BRDF chunk is named')
    # a damaged BRDF model: the export names the file
    brdf_json = os.path.join(fx.model, 'brdf', 'brdf.json')
    open(brdf_json, 'w').write('{')
    r = gonioctl('model', 'export', '--web', os.path.join(fx.dir, 'w3'), fx.model, ok=False)
    print('gonioctl model export: exit %d: %s' % (r.returncode, r.stderr.strip()))
    check(r.returncode == 6 and 'brdf.json' in r.stderr, 'a damaged BRDF model is named')


def main():
    if not browser.CHROMIUM:
        print('chromium is not installed: skipped', file=sys.stderr)
        sys.exit(77)
    cases = {'match': test_match, 'drag': test_drag, 'offline': test_offline, 'bad': test_bad,
             'brdf': test_brdf}
    if len(sys.argv) != 2 or sys.argv[1] not in cases:
        print('usage: test-viewer.py ' + '|'.join(cases), file=sys.stderr)
        sys.exit(2)
    fx = Fixture(brdf=sys.argv[1] == 'brdf')
    t0 = time.time()
    try:
        cases[sys.argv[1]](fx)
    finally:
        fx.close()
    print('%s: %.1f s' % (sys.argv[1], time.time() - t0))


main()
