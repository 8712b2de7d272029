"""browser.py - headless Chromium driven over the DevTools protocol on a pipe (stdlib only),
for the viewer's tests (tests/appearance/test-viewer.py) and bench/viewer: open a page, run
JavaScript, wait for a condition, drag the mouse, read the console and the network."""
import base64
import json
import os
import select
import shutil
import subprocess
import tempfile
import time

CHROMIUM = shutil.which('chromium') or shutil.which('chromium-browser')

# software WebGL2 (SwiftShader through ANGLE), no network beyond loopback, no first-run noise
FLAGS = ['--headless=new', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
         '--ignore-gpu-blocklist', '--no-first-run', '--no-default-browser-check',
         '--disable-extensions', '--disable-background-networking', '--disable-sync',
         '--disable-component-update', '--disable-default-apps', '--mute-audio',
         '--proxy-server=127.0.0.1:9',
         '--remote-debugging-pipe']


class Browser:
    """One Chromium process and one page target."""

    def __init__(self, width=1280, height=800, extra_flags=()):
        if not CHROMIUM:
            raise FileNotFoundError('chromium is not installed (apt-get install chromium)')
        self.profile = tempfile.mkdtemp(prefix='gonio-chromium-')
        to_child, self._w = os.pipe()
        self._r, from_child = os.pipe()
        args = [CHROMIUM] + FLAGS + list(extra_flags) + [
            f'--user-data-dir={self.profile}', f'--window-size={width},{height}', 'about:blank']
        # DevTools reads commands on fd 3 and writes replies on fd 4
        self.proc = subprocess.Popen(
            args, pass_fds=(3, 4), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            preexec_fn=lambda: (os.dup2(to_child, 3), os.dup2(from_child, 4)))
        os.close(to_child)
        os.close(from_child)
        self._buf = b''
        self._id = 0
        self.events = []
        target = self.call('Target.createTarget', url='about:blank')['targetId']
        self.session = self.call('Target.attachToTarget', targetId=target, flatten=True)['sessionId']
        for domain in ('Page', 'Runtime', 'Log', 'Network'):
            self.call(f'{domain}.enable', session=True)

    def close(self):
        try:
            self.call('Browser.close')
        except (OSError, RuntimeError):
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._w)
        os.close(self._r)
        shutil.rmtree(self.profile, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _read_message(self, timeout):
        end = time.time() + timeout
        while b'\0' not in self._buf:
            if time.time() > end or self.proc.poll() is not None:
                raise RuntimeError('chromium stopped answering')
            ready, _, _ = select.select([self._r], [], [], 0.5)
            if ready:
                data = os.read(self._r, 1 << 20)
                if not data:
                    raise RuntimeError('chromium closed its DevTools pipe')
                self._buf += data
        msg, self._buf = self._buf.split(b'\0', 1)
        return json.loads(msg)

    def call(self, method, session=False, timeout=60, **params):
        """Sends one DevTools command and returns its result; events seen meanwhile are kept."""
        self._id += 1
        msg = {'id': self._id, 'method': method, 'params': params}
        if session:
            msg['sessionId'] = self.session
        os.write(self._w, json.dumps(msg).encode() + b'\0')
        while True:
            m = self._read_message(timeout)
            if m.get('id') == self._id:
                if 'error' in m:
                    raise RuntimeError(f'{method}: {m["error"]}')
                return m.get('result', {})
            if 'method' in m:
                self.events.append(m)

    def open(self, url):
        self.call('Page.navigate', session=True, url=url)

    def eval(self, expr, timeout=60):
        """The value of JavaScript expression expr (promises awaited)."""
        r = self.call('Runtime.evaluate', session=True, timeout=timeout, expression=expr,
                      returnByValue=True, awaitPromise=True)
        if 'exceptionDetails' in r:
            raise RuntimeError(f'{expr}: {r["exceptionDetails"]}')
        return r['result'].get('value')

    def wait(self, expr, timeout=60):
        """Waits until expr is truthy; returns its value."""
        end = time.time() + timeout
        while time.time() < end:
            try:
                v = self.eval(expr)
            except RuntimeError:  # the page is not there yet
                v = None
            if v:
                return v
            time.sleep(0.1)
        raise TimeoutError(f'{expr} still false after {timeout} s')

    def drag(self, x0, y0, x1, y1, steps=8, shift=False):
        """A left-button drag from (x0, y0) to (x1, y1) in CSS pixels of the page."""
        mods = 8 if shift else 0
        self.call('Input.dispatchMouseEvent', session=True, type='mouseMoved', x=x0, y=y0,
                  modifiers=mods)
        self.call('Input.dispatchMouseEvent', session=True, type='mousePressed', x=x0, y=y0,
                  button='left', buttons=1, clickCount=1, modifiers=mods)
        for i in range(1, steps + 1):
            x, y = x0 + (x1 - x0) * i / steps, y0 + (y1 - y0) * i / steps
            self.call('Input.dispatchMouseEvent', session=True, type='mouseMoved', x=x, y=y,
                      button='left', buttons=1, modifiers=mods)
        self.call('Input.dispatchMouseEvent', session=True, type='mouseReleased', x=x1, y=y1,
                  button='left', buttons=0, clickCount=1, modifiers=mods)

    def errors(self):
        """Console errors, uncaught exceptions and failed loads seen so far."""
        out = []
        for e in self.events:
            p = e.get('params', {})
            if e['method'] == 'Runtime.exceptionThrown':
                out.append(p['exceptionDetails'].get('text', 'exception'))
            elif e['method'] == 'Runtime.consoleAPICalled' and p.get('type') == 'error':
                out.append(' '.join(str(a.get('value', a.get('description'))) for a in p['args']))
            elif e['method'] == 'Log.entryAdded' and p['entry'].get('level') == 'error':
                out.append(p['entry'].get('text', ''))
            elif e['method'] == 'Network.loadingFailed':
                out.append('failed to load: ' + p.get('errorText', ''))
        return out

    def bytes_received(self):
        """Bytes the page received (encoded, as on the wire) over the loads finished so far."""
        return sum(e['params'].get('encodedDataLength', 0) for e in self.events
                   if e['method'] == 'Network.loadingFinished')

    def pixels(self):
        """The viewer's canvas as (width, height, RGBA bytes, rows top first)."""
        w, h = self.eval("[document.getElementById('view').width, document.getElementById('view').height]")
        return w, h, base64.b64decode(self.eval('gonio.pixels()'))


def read_png(path):
    """An 8-bit grey, RGB or RGBA PNG (not interlaced) as (width, height, channels, bytes)."""
    import struct
    import zlib
    data = open(path, 'rb').read()
    if data[:8] != b'\x89PNG\r\n\x1a\n':
        raise ValueError(f'{path}: not a PNG')
    pos, idat, ihdr = 8, b'', None
    while pos < len(data):
        n, kind = struct.unpack('>I4s', data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b'IHDR':
            ihdr = struct.unpack('>IIBBBBB', body)
        elif kind == b'IDAT':
            idat += body
        pos += 12 + n
    w, h, depth, ctype, _, _, interlace = ihdr
    ch = {0: 1, 2: 3, 6: 4}[ctype]
    if depth != 8 or interlace:
        raise ValueError(f'{path}: {depth}-bit or interlaced PNG')
    raw, out, stride = zlib.decompress(idat), bytearray(), w * ch
    prev = bytearray(stride)
    for y in range(h):
        f, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - ch] if i >= ch else 0
            b, c = prev[i], prev[i - ch] if i >= ch else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        out += line
        prev = line
    return w, h, ch, bytes(out)


def write_png(path, w, h, ch, data):
    """Writes 8-bit pixels (ch 1, 3 or 4 channels, rows top first) as a PNG."""
    import struct
    import zlib
    stride = w * ch
    raw = b''.join(b'\0' + data[y * stride:(y + 1) * stride] for y in range(h))

    def chunk(kind, body):
        return struct.pack('>I', len(body)) + kind + body + struct.pack(
            '>I', zlib.crc32(kind + body) & 0xffffffff)
    ctype = {1: 0, 3: 2, 4: 6}[ch]
    with open(path, 'wb') as f:
        f.write(b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', w, h, 8, ctype, 0, 0, 0))
                + chunk(b'IDAT', zlib.compress(raw)) + chunk(b'IEND', b''))
