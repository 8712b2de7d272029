// dashboard.js - goniod's dashboard (index.html): renders the {status, session} snapshots of
// the daemon's /events stream (the same objects as the control protocol's status and
// session.status), and one live picture per camera (/preview/CAMERA.mjpg).
'use strict';

const $ = (id) => document.getElementById(id);

// Replaces el's children with the elements built from items by make.
function fill(el, items, make) {
  el.replaceChildren(...items.map(make));
}

function cell(text, cls) {
  const td = document.createElement('td');
  td.textContent = text;
  if (cls) td.className = cls;
  return td;
}

function duration(s) {
  if (s === null || s === undefined || !isFinite(s)) return '?';
  s = Math.round(s);
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), sec = s % 60;
  return (h ? h + ' h ' : '') + (h || m ? m + ' min ' : '') + sec + ' s';
}

function renderStatus(st) {
  $('state').textContent = st.state;
  $('state').className = 'badge ' + st.state;
  fill($('axes').tBodies[0], st.axes || [], (a) => {
    const tr = document.createElement('tr');
    tr.append(cell(a.name), cell(a.position.toFixed(2) + '°', 'num'),
              cell(a.homed ? 'yes' : 'no'), cell(a.moving ? 'moving' : ''));
    return tr;
  });
  const sw = (st.lamps || []).map((l) => ['lamp', l]).concat((st.lasers || []).map((l) => ['laser', l]));
  fill($('switches'), sw, ([kind, s]) => {
    const li = document.createElement('li');
    li.textContent = s.name + ': ' + (s.on ? 'on' : 'off');
    li.className = s.on ? 'on' : '';
    li.title = kind;
    return li;
  });
  $('fault').textContent = st.fault ? st.fault.device + ': ' + st.fault.message : 'none';
  $('fault').className = st.fault ? 'on' : '';
  $('dataset').textContent = st.dataset ? 'dataset ' + st.dataset.name + ' (' + st.dataset.count + ' captures)' : 'no dataset open';
  renderCameras(st.cameras || []);
}

// One <img> per camera, made once: the browser keeps the MJPEG stream open.
function renderCameras(cams) {
  const box = $('cameras');
  for (const c of cams) {
    if (document.getElementById('cam-' + c.name)) continue;
    const fig = document.createElement('figure');
    const img = document.createElement('img');
    img.id = 'cam-' + c.name;
    img.alt = c.name;
    img.src = '/preview/' + encodeURIComponent(c.name) + '.mjpg';
    const cap = document.createElement('figcaption');
    cap.textContent = c.name + ' (' + c.width + '×' + c.height + ')';
    fig.append(img, cap);
    box.append(fig);
  }
}

function renderSession(s) {
  const box = $('session');
  if (!s || !s.name) {
    box.textContent = 'no session';
    $('progress').value = 0;
    $('progress-text').textContent = '';
    return;
  }
  const state = s.state === 'none' ? 'ended, ' + s.ended : s.state;
  box.textContent = 'session ' + s.name + ' (' + s.dataset + '): ' + state + (s.reason ? ': ' + s.reason : '');
  $('progress').max = Math.max(s.planned, 1);
  $('progress').value = s.captured;
  $('progress-text').textContent = s.captured + ' / ' + s.planned + ' captured, ' +
    (s.rate_per_s ? s.rate_per_s.toFixed(1) + ' a second, ' : '') + 'ETA ' + duration(s.eta_s);
}

window.gonio = { updates: 0, status: null, session: null };

function render(snap) {
  window.gonio.updates++;
  window.gonio.status = snap.status;
  window.gonio.session = snap.session;
  renderStatus(snap.status);
  renderSession(snap.session);
}

function connect() {
  const es = new EventSource('/events');
  es.addEventListener('status', (e) => render(JSON.parse(e.data)));
  es.onopen = () => { $('link').textContent = 'live'; };
  es.onerror = () => { $('link').textContent = 'reconnecting'; };
}

connect();
