// viewer.js - gonio's relighting viewer (docs/viewer.md), WebGL2. It computes what
// appearance/render.c and render_px.c compute (render.h): the mesh rasterised from the
// viewer's camera; per pixel the up-to-3 sampled views around the view direction (the
// views' triangulation, views.h), the point projected into each with its distortion, dropped
// where a view's depth map or mask says the view does not see it, the views' weights sampled
// bilinearly and blended; then the light term from a cube map of L(l, k, c).
// The data comes from data/*.js (base64 of gzip), loaded progressively: manifest, mesh,
// basis, then the views nearest the first view direction first. With a BRDF model in the
// folder the environment mode can shade with it instead (brdf.js); its data comes first when
// the page opens in that mode, else after the views.
'use strict';

const gonio = (() => {
  const CUBE = 32;          // AP_RENDER_CUBE
  const BIAS = 0.005;       // AP_RENDER_BIAS
  const SLOPE = 2.5;        // AP_RENDER_SLOPE
  const MARGIN = 8;         // AP_RENDER_MARGIN
  const FADE_LO = '0.10';   // AP_RENDER_FADE_LO (GLSL literals)
  const FADE_HI = '0.35';   // AP_RENDER_FADE_HI
  const FIRST_VIEWS = 3;    // views loaded before the first frame
  const VIEW_TEXELS = 9;    // RGBA32F texels of a view's parameters before its scales

  const g = {state: 'loading', error: null, loaded: 0, total: 0, frames: 0};
  const chunks = {};
  let man = null, gl = null, canvas = null;
  let progs = {}, tex = {}, meshBuf = {}, views = [], lightRows = 0, groups = 0;
  let params = {az: 0, el: 20, distance: 0, mode: 'pixel', light: 'point',
                lpos: [0, 0, 0], ldir: [0, 0, 1], env: 0, gain: 1, intensity: 0, model: 'sh'};
  let basis = null, dirty = true, lastDraw = {end: 0, ms: 0}, brdf = null;

  // ---- data ----
  g.manifest = (m) => { man = m; };
  g.chunk = (name, b64) => { chunks[name] = b64; };

  function loadScript(src) {
    return new Promise((resolve, reject) => {
      const s = document.createElement('script');
      s.src = src;
      s.onload = () => { s.remove(); resolve(); };
      s.onerror = () => reject(new Error('cannot load ' + src));
      document.head.appendChild(s);
    });
  }

  async function loadChunk(entry) {
    await loadScript('data/' + entry.chunk + '.js');
    const b64 = chunks[entry.chunk];
    delete chunks[entry.chunk];
    let buf;
    try {
      if (typeof b64 !== 'string') throw new Error('no data');
      const bin = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
      const stream = new Blob([bin]).stream().pipeThrough(new DecompressionStream('gzip'));
      buf = await new Response(stream).arrayBuffer();
      if (buf.byteLength !== entry.raw_bytes)
        throw new Error(buf.byteLength + ' bytes, expected ' + entry.raw_bytes);
    } catch (e) {
      throw new Error('data/' + entry.chunk + '.js is damaged (' + e.message + '): export the model again');
    }
    g.loaded += entry.bytes;
    progress();
    return buf;
  }

  // Bytes downloaded so far (Resource Timing: the page, its script, its data; 0 from file://).
  function downloaded() {
    return performance.getEntriesByType('navigation').concat(performance.getEntriesByType('resource'))
      .reduce((a, e) => a + (e.encodedBodySize || 0), 0);
  }

  function progress() {
    const bar = document.querySelector('#progress div');
    if (bar) bar.style.width = (g.total ? 100 * g.loaded / g.total : 0).toFixed(1) + '%';
  }

  function fail(msg) {
    g.state = 'error';
    g.error = msg;
    const m = document.getElementById('message');
    if (m) m.textContent = msg;
  }

  // ---- maths ----
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                           a[0] * b[1] - a[1] * b[0]];
  const norm = (a) => { const l = Math.hypot(a[0], a[1], a[2]); return [a[0] / l, a[1] / l, a[2] / l]; };
  const azel = (az, el) => {
    const a = az * Math.PI / 180, e = el * Math.PI / 180;
    return [Math.cos(e) * Math.cos(a), Math.cos(e) * Math.sin(a), Math.sin(e)];
  };
  const camCentre = (v) => [0, 1, 2].map((i) => -(v.R[i] * v.t[0] + v.R[3 + i] * v.t[1] + v.R[6 + i] * v.t[2]));

  // Real SH of order P at unit d (appearance/sh.c: no Condon-Shortley phase).
  function shNorm(P) {
    const n = new Float64Array(P * P);
    for (let l = 0; l < P; l++) {
      let dfact = 1;
      for (let m = 0; m <= l; m++) {
        let ratio = 1;
        if (m > 0) dfact *= 2 * m - 1;
        for (let k = l - m + 1; k <= l + m; k++) ratio *= k;
        n[l * l + l + m] = Math.sqrt((2 * l + 1) / (4 * Math.PI) / ratio) * dfact * (m ? Math.SQRT2 : 1);
      }
    }
    return n;
  }
  function shEval(P, nrm, d, y) {
    const x = d[0], yy = d[1], z = d[2];
    let c = 1, s = 0;
    for (let m = 0; m < P; m++) {
      let q0 = 1, q1 = 0;
      if (m > 0) { const cn = c * x - s * yy; s = c * yy + s * x; c = cn; }
      for (let l = m; l < P; l++) {
        let q = l === m ? 1 : l === m + 1 ? (2 * m + 1) * z : 0;
        if (l > m + 1) q = ((2 * l - 1) * z * q0 - (l + m - 1) * q1) / (l - m);
        q1 = q0; q0 = q;
        y[l * l + l + m] = nrm[l * l + l + m] * q * c;
        if (m > 0) y[l * l + l - m] = nrm[l * l + l + m] * q * s;
      }
    }
  }
  // L(l, k, c) into out[(K + 1) * 3] from SH values y (stride 1) or coefficients (stride 3).
  function lightTerm(y, stride, out) {
    const M = man.n_coef, K = man.components;
    for (let k = 0; k <= K; k++)
      for (let c = 0; c < 3; c++) {
        let s = 0;
        for (let i = 0; i < M; i++) s += basis[k * 3 * M + i * 3 + c] * y[i * stride + (stride === 3 ? c : 0)];
        out[k * 3 + c] = Math.fround(s);
      }
  }
  function cubeDir(face, s, t) {
    const d = [0, 0, 0], ax = face >> 1;
    d[ax] = face % 2 ? -1 : 1;
    d[ax === 0 ? 1 : 0] = s;
    d[ax === 2 ? 1 : 2] = t;
    return d;
  }


  const {VS, MAIN_VS, DEPTH_FS, MAIN_FS} = gonioShaders({CUBE, VIEW_TEXELS, FADE_LO, FADE_HI});

  // ---- GL ----
  function compile(vs, fs) {
    const p = gl.createProgram();
    for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
      const s = gl.createShader(type);
      gl.shaderSource(s, src);
      gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error('shader: ' + gl.getShaderInfoLog(s));
      gl.attachShader(p, s);
    }
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error('program: ' + gl.getProgramInfoLog(p));
    const u = {};
    for (let i = 0; i < gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS); i++) {
      const a = gl.getActiveUniform(p, i), name = a.name.replace(/\[0\]$/, '');
      u[name] = gl.getUniformLocation(p, a.name);
    }
    return {p, u};
  }

  function floatTexture(w, h, data) {
    const t = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, w, h, 0, gl.RGBA, gl.FLOAT, data);
    setNearest(gl.TEXTURE_2D);
    return t;
  }
  function setNearest(target) {
    gl.texParameteri(target, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(target, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(target, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(target, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  }
  function arrayTexture(internal, w, h, layers) {
    const t = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, t);
    gl.texStorage3D(gl.TEXTURE_2D_ARRAY, 1, internal, w, h, layers);
    setNearest(gl.TEXTURE_2D_ARRAY);
    return t;
  }

  // A pinhole projection to clip space, pixel centres at integers (OpenCV), flipY for the
  // canvas (row 0 on top); z from the depth range [near, far].
  function pinholeUniforms(u, fx, fy, cx, cy, w, h, near, far, flipY) {
    gl.uniform4f(u.proj, 2 * fx / w, (flipY ? -2 : 2) * fy / h,
                 2 * (cx + 0.5) / w - 1, flipY ? 1 - 2 * (cy + 0.5) / h : 2 * (cy + 0.5) / h - 1);
    gl.uniform2f(u.depthRange, near, far);
  }

  // ---- setup ----
  function setupGL() {
    canvas = document.getElementById('view');
    gl = canvas.getContext('webgl2', {preserveDrawingBuffer: true, antialias: false,
                                      alpha: true, premultipliedAlpha: false});
    if (!gl) throw new Error('This viewer needs WebGL2, which this browser does not offer ' +
                             '(enable hardware acceleration or use a current Chrome, Firefox or Safari).');
    if (!gl.getExtension('EXT_color_buffer_float'))
      throw new Error('This viewer needs float render targets (EXT_color_buffer_float), which this browser lacks.');
    progs.depth = compile(VS, DEPTH_FS);
    progs.main = compile(MAIN_VS, MAIN_FS);
  }

  // render.c build_vertex_normals: a closed mesh's (front: its winding, 1 or -1) vertex
  // normals, the area-weighted mean of its faces'; null for an open mesh (front 0).
  function vertexNormals(pos, idx, front) {
    if (!front) return null;
    const acc = new Float64Array(pos.length), out = new Float32Array(pos.length);
    for (let t = 0; t < idx.length; t += 3) {
      const a = 3 * idx[t], b = 3 * idx[t + 1], c = 3 * idx[t + 2];
      const u = [0, 1, 2].map((j) => pos[b + j] - pos[a + j]);
      const v = [0, 1, 2].map((j) => pos[c + j] - pos[a + j]);
      const n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
      for (const k of [a, b, c])
        for (let j = 0; j < 3; j++) acc[k + j] += front * n[j];
    }
    for (let i = 0; i < pos.length; i += 3) {
      const len = Math.hypot(acc[i], acc[i + 1], acc[i + 2]);
      for (let j = 0; j < 3; j++) out[i + j] = len > 0 ? acc[i + j] / len : 0;
    }
    return out;
  }

  function uploadMesh(buf) {
    const nv = man.mesh.vertices, nt = man.mesh.triangles;
    const pos = new Float32Array(buf, 0, nv * 3), idx = new Uint32Array(buf, nv * 12, nt * 3);
    meshBuf.vao = gl.createVertexArray();
    gl.bindVertexArray(meshBuf.vao);
    const vb = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, vb);
    gl.bufferData(gl.ARRAY_BUFFER, pos, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
    const nrm = vertexNormals(pos, idx, man.mesh.front || 0);
    if (nrm) {
      const nb = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, nb);
      gl.bufferData(gl.ARRAY_BUFFER, nrm, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(3);
      gl.vertexAttribPointer(3, 3, gl.FLOAT, false, 0, 0);
    } else {
      gl.vertexAttrib3f(3, 0, 0, 0);
    }
    const ib = gl.createBuffer();
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ib);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, idx, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    meshBuf.count = nt * 3;
    let r = 0;
    for (let i = 0; i < nv; i++)
      r = Math.max(r, Math.hypot(pos[3 * i] - man.centre[0], pos[3 * i + 1] - man.centre[1], pos[3 * i + 2] - man.centre[2]));
    meshBuf.radius = r;
  }

  // The cube map of L(l, k, c) (render.c build_light_cube), lightRows texels of 4 a direction.
  function uploadLight() {
    const K = man.components, row = (K + 1) * 3, P = man.order, nrm = shNorm(P);
    const y = new Float64Array(P * P), out = new Float32Array(row);
    lightRows = Math.ceil(row / 4);
    const data = new Float32Array(6 * CUBE * CUBE * lightRows * 4);
    for (let face = 0; face < 6; face++)
      for (let it = 0; it < CUBE; it++)
        for (let is = 0; is < CUBE; is++) {
          const d = cubeDir(face, Math.fround(2 * (is + 0.5) / CUBE - 1), Math.fround(2 * (it + 0.5) / CUBE - 1));
          shEval(P, nrm, norm(d), y);
          lightTerm(y, 1, out);
          data.set(out, ((face * CUBE + it) * CUBE + is) * lightRows * 4);
        }
    tex.light = floatTexture(CUBE * lightRows, 6 * CUBE, data);
  }

  function uploadTriangulation() {
    const t = man.triangulation, nv = man.views.length;
    const faces = new Float32Array(Math.max(1, t.faces.length) * 20);
    t.faces.forEach((f, i) => {
      faces.set([f[0], f[1], f[2], 0], 20 * i);
      for (let j = 0; j < 3; j++) faces.set([f[3 + 3 * j], f[4 + 3 * j], f[5 + 3 * j], 0], 20 * i + 4 + 4 * j);
      faces.set([f[12], f[13], f[14], 0], 20 * i + 16);
    });
    const start = new Float32Array(t.start.length * 4);
    t.start.forEach((f, i) => { start[4 * i] = f; });
    tex.start = floatTexture(t.cube, 6 * t.cube, start);
    const bnd = new Float32Array(Math.max(1, t.boundary.length) * 8);
    t.boundary.forEach((b, i) => bnd.set([b[0], b[1], 0, 0, b[2], b[3], b[4], 0], 8 * i));
    const dirs = new Float32Array(nv * 4);
    man.views.forEach((v, i) => dirs.set([v.dir[0], v.dir[1], v.dir[2], t.dup[i] ? 1 : 0], 4 * i));
    tex.faces = floatTexture(5, Math.max(1, t.faces.length), faces);
    tex.bnd = floatTexture(2, Math.max(1, t.boundary.length), bnd);
    tex.dirs = floatTexture(1, nv, dirs);
  }

  // Every view's parameters (sampleView's rows) and the arrays its data goes into.
  function setupViews() {
    const K = man.components;
    groups = Math.ceil(K / 4);
    let cw = 1, ch = 1, dw = 1, dh = 1;
    views = man.views.map((v) => {
      const mx = Math.floor(v.width / MARGIN), my = Math.floor(v.height / MARGIN);
      cw = Math.max(cw, v.crop[2]); ch = Math.max(ch, v.crop[3]);
      dw = Math.max(dw, v.crop[2] + 2 * mx); dh = Math.max(dh, v.crop[3] + 2 * my);
      return Object.assign({mx, my, loaded: false}, v);
    });
    tex.viewData = new Float32Array(views.length * (VIEW_TEXELS + 2 * groups) * 4);
    tex.mask = arrayTexture(gl.R8, cw, ch, views.length);
    tex.weights = arrayTexture(gl.RGBA8, cw, ch, views.length * groups);
    tex.depth = arrayTexture(gl.R32F, dw, dh, views.length);
    tex.depthRb = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, tex.depthRb);
    gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT24, dw, dh);
    tex.fb = gl.createFramebuffer();
    views.forEach((v, i) => writeViewData(v, i));
    uploadViewData();
  }

  function writeViewData(v, i) {
    const n = VIEW_TEXELS + 2 * groups, o = i * n * 4, d = tex.viewData, k = v.dist;
    const distorted = k.some((x) => x !== 0) ? 1 : 0;
    d.set([v.R[0], v.R[1], v.R[2], v.t[0], v.R[3], v.R[4], v.R[5], v.t[1],
           v.R[6], v.R[7], v.R[8], v.t[2], v.fx, v.fy, v.cx, v.cy, k[0], k[1], k[2], k[3],
           k[4], v.width, v.height, v.loaded ? 1 : 0,
           v.mx, v.my, v.width + 2 * v.mx, v.height + 2 * v.my,
           v.crop[0], v.crop[1], v.crop[2], v.crop[3],
           v.crop[0], v.crop[1], Math.fround(Math.max(BIAS, SLOPE / v.fx)), distorted], o);
    for (let j = 0; j < man.components; j++) {
      d[o + (VIEW_TEXELS + (j >> 2)) * 4 + (j & 3)] = v.scale[j];
      d[o + (VIEW_TEXELS + groups + (j >> 2)) * 4 + (j & 3)] = v.offset[j];
    }
  }

  function uploadViewData() {
    if (tex.view) gl.deleteTexture(tex.view);
    tex.view = floatTexture(VIEW_TEXELS + 2 * groups, views.length, tex.viewData);
  }

  // View i's mask and weights into the arrays, its depth map rendered (render.c build_view:
  // the pinhole camera with margins, here cropped to the mask's box grown by the margins).
  function uploadView(i, buf) {
    const v = views[i], w = v.crop[2], h = v.crop[3], n = w * h, bytes = new Uint8Array(buf);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex.mask);
    gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, i, w, h, 1, gl.RED, gl.UNSIGNED_BYTE, bytes.subarray(0, n));
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex.weights);
    for (let gi = 0; gi < groups; gi++)
      gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, i * groups + gi, w, h, 1, gl.RGBA, gl.UNSIGNED_BYTE,
                       bytes.subarray(n + gi * n * 4, n + (gi + 1) * n * 4));
    renderDepth(v, i);
    v.loaded = true;
    writeViewData(v, i);
    uploadViewData();
  }

  function renderDepth(v, i) {
    const w = v.crop[2] + 2 * v.mx, h = v.crop[3] + 2 * v.my, pr = progs.depth;
    gl.bindFramebuffer(gl.FRAMEBUFFER, tex.fb);
    gl.framebufferTextureLayer(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, tex.depth, 0, i);
    gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, tex.depthRb);
    gl.viewport(0, 0, w, h);
    gl.clearBufferfv(gl.COLOR, 0, [-1, 0, 0, 0]);
    gl.clear(gl.DEPTH_BUFFER_BIT);
    gl.useProgram(pr.p);
    cameraUniforms(pr.u, v.R, v.t);
    const dist = Math.hypot(...sub(camCentre(v), man.centre));
    pinholeUniforms(pr.u, v.fx, v.fy, v.cx + v.mx - v.crop[0], v.cy + v.my - v.crop[1], w, h,
                    Math.max(1e-3, dist - 2 * meshBuf.radius), dist + 2 * meshBuf.radius, false);
    drawMesh();
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  }

  function cameraUniforms(u, R, t) {
    // column-major: the columns of R are its rows' transposes
    gl.uniformMatrix3fv(u.Rm, false, [R[0], R[3], R[6], R[1], R[4], R[7], R[2], R[5], R[8]]);
    gl.uniform3f(u.tv, t[0], t[1], t[2]);
  }

  function drawMesh(depthFunc = gl.LESS) {
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(depthFunc);
    gl.disable(gl.CULL_FACE);
    gl.bindVertexArray(meshBuf.vao);
    gl.drawElements(gl.TRIANGLES, meshBuf.count, gl.UNSIGNED_INT, 0);
    gl.bindVertexArray(null);
  }

  // ---- a frame ----
  // The viewer's camera as model_render.c make_camera builds it: the intrinsics of the
  // sampled view nearest the direction, scaled to fit the canvas (make_camera scales to the
  // width: the same when the aspect ratios agree), at that view's distance (or
  // the zoomed one) from the mesh centre, looking at it with +z up (render.c look_at).
  function frameCamera() {
    const d = azel(params.az, params.el), c = man.centre, W = canvas.width, H = canvas.height;
    let near = views[0], best = -2;
    for (const v of views) if (dot(v.dir, d) > best) { best = dot(v.dir, d); near = v; }
    const dist = params.distance > 0 ? params.distance : Math.hypot(...sub(camCentre(near), c));
    const s = Math.min(W / near.width, H / near.height), eye = [0, 1, 2].map((i) => c[i] + dist * d[i]);
    const f = norm(sub(c, eye));
    const up = Math.abs(f[2]) > 1 - 1e-12 ? [0, 1, 0] : [0, 0, 1];
    const rt = norm(cross(f, up)), dn = cross(f, rt);
    const R = [...rt, ...dn, ...f], t = [0, 1, 2].map((i) => -dot(R.slice(3 * i, 3 * i + 3), eye));
    return {R, t, eye, dist, fx: near.fx * s, fy: near.fy * s, cx: W / 2 - 0.5, cy: H / 2 - 0.5, W, H};
  }

  // render.c frame_light: the scale and, for a directional or environment light, L itself.
  function frameLight(u) {
    const i0 = man.light.intensity > 0 ? man.light.intensity : 1;
    const s = (params.intensity > 0 ? params.intensity : i0) / i0;
    const L = new Float32Array(100);
    if (params.light === 'point') {
      let d0 = man.light.distance_mm;
      if (!(d0 > 0)) d0 = Math.hypot(...sub(params.lpos, man.centre));
      gl.uniform1i(u.pointLight, 1);
      gl.uniform3f(u.lpos, ...params.lpos);
      gl.uniform1f(u.lscale, Math.fround(s * d0 * d0));
      return;
    }
    gl.uniform1i(u.pointLight, 0);
    if (params.light === 'dir') {
      const y = new Float64Array(man.n_coef);
      shEval(man.order, shNorm(man.order), norm(params.ldir), y);
      lightTerm(y, 1, L);
      gl.uniform1f(u.lscale, s);
    } else {
      lightTerm(man.envs[params.env].coef, 3, L);
      gl.uniform1f(u.lscale, 1);
    }
    gl.uniform1fv(u.lconst, L);
  }

  function bindTextures(u) {
    const units = [['viewTex', gl.TEXTURE_2D, tex.view], ['faceTex', gl.TEXTURE_2D, tex.faces],
                   ['bndTex', gl.TEXTURE_2D, tex.bnd], ['dirTex', gl.TEXTURE_2D, tex.dirs],
                   ['lightTex', gl.TEXTURE_2D, tex.light], ['maskArr', gl.TEXTURE_2D_ARRAY, tex.mask],
                   ['weightArr', gl.TEXTURE_2D_ARRAY, tex.weights], ['depthArr', gl.TEXTURE_2D_ARRAY, tex.depth],
                   ['startTex', gl.TEXTURE_2D, tex.start]];
    units.forEach(([name, target, t], i) => {
      gl.activeTexture(gl.TEXTURE0 + i);
      gl.bindTexture(target, t);
      gl.uniform1i(u[name], i);
    });
    gl.activeTexture(gl.TEXTURE0);
  }

  function draw() {
    const cam = frameCamera(), pr = progs.main, u = pr.u, c = man.centre;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, cam.W, cam.H);
    gl.clearColor(0, 0, 0, 0);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    if (brdfShown()) {
      const ground = man.brdf.envs[params.env].ground.radius, reach = 2 * meshBuf.radius + ground;
      brdf.draw(params.env, cam, params.gain, Math.max(1e-3, cam.dist - reach), cam.dist + reach);
      g.frames++;
      dirty = false;
      return;
    }
    gl.useProgram(pr.p);
    cameraUniforms(u, cam.R, cam.t);
    pinholeUniforms(u, cam.fx, cam.fy, cam.cx, cam.cy, cam.W, cam.H,
                    Math.max(1e-3, cam.dist - 2 * meshBuf.radius), cam.dist + 2 * meshBuf.radius, true);
    bindTextures(u);
    const t = man.triangulation;
    gl.uniform1i(u.K, man.components);
    gl.uniform1i(u.G, groups);
    gl.uniform1i(u.nFaces, t.faces.length);
    gl.uniform1i(u.nBnd, t.boundary.length);
    gl.uniform1i(u.nViews, views.length);
    gl.uniform1i(u.pixelMode, params.mode === 'pixel' ? 1 : 0);
    gl.uniform1i(u.lightTexels, lightRows);
    gl.uniform1i(u.startSide, t.cube);
    gl.uniform3f(u.camC, ...cam.eye);
    gl.uniform3f(u.objDir, ...norm(sub(cam.eye, c)));
    gl.uniform1f(u.gain, params.gain);
    frameLight(u);
    depthPrepass(cam);
    gl.useProgram(pr.p);
    gl.depthMask(false);
    drawMesh(gl.EQUAL); // each visible pixel shaded once (the shader may discard)
    gl.depthMask(true);
    g.frames++;
    dirty = false;
  }

  // The frame's depth alone, so that the main pass shades only what is seen.
  function depthPrepass(cam) {
    const pr = progs.depth;
    gl.useProgram(pr.p);
    cameraUniforms(pr.u, cam.R, cam.t);
    pinholeUniforms(pr.u, cam.fx, cam.fy, cam.cx, cam.cy, cam.W, cam.H,
                    Math.max(1e-3, cam.dist - 2 * meshBuf.radius), cam.dist + 2 * meshBuf.radius, true);
    gl.colorMask(false, false, false, false);
    drawMesh();
    gl.colorMask(true, true, true, true);
  }

  // Whether the frame is the BRDF model's: the environment mode with model=brdf, once loaded.
  const brdfShown = () => params.light === 'env' && params.model === 'brdf' && brdf && brdf.ready();

  // ---- the page ----
  function readParams() {
    const q = new URLSearchParams(location.search), nums = (s, n) => {
      const v = (s || '').split(',').map(Number);
      return v.length === n && v.every(Number.isFinite) ? v : null;
    };
    const v0 = views.length ? views[0].dir : man.views[0].dir;
    params.az = Math.atan2(v0[1], v0[0]) * 180 / Math.PI;
    params.el = Math.asin(Math.max(-1, Math.min(1, v0[2]))) * 180 / Math.PI;
    const view = nums(q.get('view'), 2);
    if (view) [params.az, params.el] = view;
    params.laz = params.az + 40;
    params.lel = 45;
    placeLight();
    const light = nums(q.get('light'), 3), dir = nums(q.get('dir'), 3);
    if (light) { params.light = 'point'; params.lpos = light; }
    if (dir) { params.light = 'dir'; params.ldir = dir; }
    if (q.has('env')) {
      const e = man.envs.findIndex((x, i) => x.name === q.get('env') || String(i) === q.get('env'));
      params.light = 'env';
      params.env = Math.max(0, e);
    }
    if (q.get('mode') === 'object') params.mode = 'object';
    if (brdf) params.model = q.get('model') === 'sh' ? 'sh' : 'brdf';
    const size = (q.get('size') || '').match(/^(\d+)x(\d+)$/);
    if (size) {
      canvas.width = +size[1];
      canvas.height = +size[2];
    } else {
      fitWindow();
      window.addEventListener('resize', () => { fitWindow(); dirty = true; });
    }
    const gain = Number(q.get('gain')), dist = Number(q.get('distance')), inten = Number(q.get('intensity'));
    if (gain > 0) params.gain = gain;
    if (dist > 0) params.distance = dist;
    if (inten > 0) params.intensity = inten;
  }

  // The canvas fills the window below the bar.
  function fitWindow() {
    const bar = document.getElementById('bar').offsetHeight;
    canvas.width = Math.max(64, window.innerWidth);
    canvas.height = Math.max(64, window.innerHeight - bar);
    canvas.style.marginTop = bar + 'px';
  }

  function placeLight() {
    const d = azel(params.laz, params.lel);
    params.lpos = [0, 1, 2].map((i) => man.centre[i] + man.light.distance_mm * d[i]);
    params.ldir = d;
  }

  function setupUI() {
    const mode = document.getElementById('mode'), light = document.getElementById('light');
    const gain = document.getElementById('gain'), model = document.getElementById('model');
    document.getElementById('title').textContent = 'gonio: ' + man.name;
    document.getElementById('modelLabel').hidden = !brdf;
    model.value = params.model;
    model.onchange = () => { params.model = model.value; dirty = true; };
    man.envs.forEach((e, i) => light.add(new Option('environment: ' + e.name, 'env' + i)));
    mode.value = params.mode;
    light.value = params.light === 'env' ? 'env' + params.env : params.light;
    gain.value = Math.log2(params.gain);
    mode.onchange = () => { params.mode = mode.value; dirty = true; };
    light.onchange = () => {
      params.light = light.value.startsWith('env') ? 'env' : light.value;
      params.env = params.light === 'env' ? +light.value.slice(3) : params.env;
      dirty = true;
    };
    gain.oninput = () => { params.gain = Math.pow(2, +gain.value); dirty = true; };
    let drag = null;
    canvas.oncontextmenu = (e) => e.preventDefault();
    canvas.onpointerdown = (e) => {
      drag = {x: e.clientX, y: e.clientY, light: e.shiftKey || e.button === 2};
      canvas.setPointerCapture(e.pointerId);
    };
    canvas.onpointermove = (e) => {
      if (!drag) return;
      const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
      drag.x = e.clientX; drag.y = e.clientY;
      if (drag.light) {
        params.laz -= dx * 0.5;
        params.lel = Math.max(-89, Math.min(89, params.lel + dy * 0.5));
        placeLight();
        if (params.light === 'env') params.light = 'point', light.value = 'point';
      } else {
        params.az -= dx * 0.5;
        params.el = Math.max(-89, Math.min(89, params.el + dy * 0.5));
      }
      dirty = true;
    };
    canvas.onpointerup = () => { drag = null; };
    canvas.onwheel = (e) => {
      e.preventDefault();
      const cur = params.distance > 0 ? params.distance : frameCamera().dist;
      params.distance = cur * Math.pow(1.1, Math.sign(e.deltaY));
      dirty = true;
    };
  }

  function status(text) {
    const s = document.getElementById('status');
    if (s) s.textContent = text;
  }

  // Draws when the user changed something; while views still arrive (they are drawn as the
  // last arrives), at most once a second and never more than a fifth of the time, so that a
  // slow GL does not hold the loading up.
  function loop() {
    const now = performance.now();
    if (dirty && (g.state === 'complete' ||
                  (g.state === 'first' && now - lastDraw.end > Math.max(1000, 4 * lastDraw.ms)))) {
      draw();
      lastDraw = {end: performance.now(), ms: performance.now() - now};
    }
    requestAnimationFrame(loop);
  }

  async function start() {
    try {
      canvas = document.getElementById('view');
      await loadScript('data/model.js');
      if (!man) throw new Error('data/model.js holds no model');
      if (man.format !== 'gonio-web 1')
        throw new Error('this folder holds "' + man.format + '", which this viewer does not read ' +
                        '(it reads gonio-web 1): export the model again with this gonioctl');
      setupGL();
      g.total = man.mesh.bytes + man.basis.bytes + man.views.reduce((a, v) => a + v.bytes, 0);
      const maxTex = gl.getParameter(gl.MAX_TEXTURE_SIZE);
      if (man.brdf && Math.max(man.brdf.atlas.width, man.brdf.atlas.height) > maxTex) {
        g.note = `the BRDF model is not shown: its atlas (${man.brdf.atlas.width}x${man.brdf.atlas.height} ` +
          `texels) exceeds this browser's largest texture (${maxTex})`;
      } else if (man.brdf) {
        brdf = gonioBrdf({gl, compile, cameraUniforms, pinholeUniforms, setNearest, shNorm, depthFS: DEPTH_FS});
        g.total += brdf.bytes(man.brdf);
      }
      readParams();
      setupUI();
      status('loading the mesh and the basis');
      const [meshB, basisB] = await Promise.all([loadChunk(man.mesh), loadChunk(man.basis)]);
      uploadMesh(meshB);
      basis = new Float32Array(basisB);
      uploadLight();
      uploadTriangulation();
      setupViews();
      const brdfFirst = brdf && params.model === 'brdf' && params.light === 'env';
      if (brdfFirst) {
        await loadBrdf();
        firstFrame();
      }
      const d = azel(params.az, params.el);
      const order = views.map((v, i) => i).sort((a, b) => dot(views[b].dir, d) - dot(views[a].dir, d));
      let n = 0;
      for (const i of order) {
        uploadView(i, await loadChunk(views[i]));
        status('views: ' + ++n + ' of ' + views.length);
        if (n === Math.min(FIRST_VIEWS, views.length)) firstFrame();
      }
      if (brdf && !brdfFirst) await loadBrdf();
      draw();
      g.state = 'complete';
      status(views.length + ' views, ' + man.mesh.triangles + ' triangles' +
             (brdf ? ', BRDF model: ' + man.brdf.texels.fitted + ' texels fitted' : '') +
             (g.note ? '; ' + g.note : ''));
    } catch (e) {
      fail(e.message);
    }
  }

  // The first frame, once: the redraw loop starts.
  function firstFrame() {
    if (g.state !== 'loading') return;
    draw();
    g.firstFrameBytes = downloaded();
    g.state = 'first';
    requestAnimationFrame(loop);
  }

  async function loadBrdf() {
    status('loading the BRDF model');
    await brdf.load(man.brdf, loadChunk);
  }

  // ---- for scripts and tests ----
  // Changes the view (az, el), light ({light: [x,y,z]} | {dir: [...]} | {env: i}), mode, gain
  // or model ('sh' | 'brdf': the environment mode's).
  g.set = (p) => {
    if (p.view) [params.az, params.el] = p.view;
    if (p.light) { params.light = 'point'; params.lpos = p.light; }
    if (p.dir) { params.light = 'dir'; params.ldir = p.dir; }
    if (p.env !== undefined) { params.light = 'env'; params.env = p.env; }
    if (p.mode) params.mode = p.mode;
    if (p.gain) params.gain = p.gain;
    if (p.model) params.model = p.model;
    draw();
  };
  // The frame's camera (OpenCV pinhole: R row-major, t, intrinsics, size).
  g.camera = () => {
    const c = frameCamera();
    return {R: c.R, t: c.t, fx: c.fx, fy: c.fy, cx: c.cx, cy: c.cy, width: c.W, height: c.H};
  };
  // The canvas as base64 RGBA, rows top first.
  g.pixels = () => {
    const w = canvas.width, h = canvas.height, px = new Uint8Array(w * h * 4), out = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    for (let y = 0; y < h; y++) out.set(px.subarray((h - 1 - y) * w * 4, (h - y) * w * 4), y * w * 4);
    let s = '';
    for (let i = 0; i < out.length; i += 0x8000) s += String.fromCharCode.apply(null, out.subarray(i, i + 0x8000));
    return btoa(s);
  };
  // Frames per second over n frames drawn back to back, each waited for.
  g.fps = (n) => {
    const px = new Uint8Array(4), t0 = performance.now();
    for (let i = 0; i < n; i++) {
      params.laz += 1;
      placeLight();
      draw();
      gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
    }
    return n * 1000 / (performance.now() - t0);
  };

  window.addEventListener('load', start);

  return g;
})();
