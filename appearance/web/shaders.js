// shaders.js - the GLSL of gonio's relighting viewer (viewer.js, docs/viewer.md): the vertex
// shader shared by every pass (object frame to an OpenCV pinhole camera's clip space), the
// depth pass (camera z into a float target: the views' depth maps, the frame's pre-pass), and
// the main pass, which computes appearance/render_px.c's per-pixel work: the views around the
// view direction (views.c), their weights sampled where they see the point, the light term.
'use strict';

// The vertex shader of every mesh pass: object frame to an OpenCV pinhole camera's clip space,
// with decl and body adding a pass's own inputs and outputs.
function gonioVertexShader(decl = '', body = '') {
  return `#version 300 es
layout(location = 0) in vec3 pos;
uniform mat3 Rm;
uniform vec3 tv;
uniform vec4 proj;
uniform vec2 depthRange;
out vec3 vPos;
out float vZ;
${decl}
void main() {
  vec3 xc = Rm * pos + tv;
  float n = depthRange.x, f = depthRange.y;
  vPos = pos;
  vZ = xc.z;
  ${body}
  gl_Position = vec4(proj.x * xc.x + proj.z * xc.z, proj.y * xc.y + proj.w * xc.z,
                     (xc.z * (f + n) - 2.0 * f * n) / (f - n), xc.z);
}`;
}

// The sources, with the constants the page shares with the renderer (CUBE, VIEW_TEXELS,
// FADE_LO, FADE_HI).
function gonioShaders({CUBE, VIEW_TEXELS, FADE_LO, FADE_HI}) {
  const VS = gonioVertexShader();
  // the main pass's: also the vertex normal (render.c build_vertex_normals; 0 0 0: none)
  const MAIN_VS = gonioVertexShader(`layout(location = 3) in vec3 nrmIn;
out vec3 vNrm;`, `vNrm = nrmIn;`);

  const DEPTH_FS = `#version 300 es
precision highp float;
in vec3 vPos;
in float vZ;
out vec4 o;
void main() { o = vec4(vZ, 0.0, 0.0, 1.0); }`;

  const MAIN_FS = `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2DArray;
uniform highp sampler2D viewTex, faceTex, bndTex, dirTex, lightTex, startTex;
uniform highp sampler2DArray maskArr, weightArr, depthArr;
uniform int K, G, nFaces, nBnd, nViews, pixelMode, pointLight, lightTexels, startSide;
uniform vec3 camC, objDir, lpos;
uniform float lscale, gain;
uniform float lconst[100];
in vec3 vPos;
in float vZ;
in vec3 vNrm;
out vec4 outColor;
float acc[32];

vec4 vt(int v, int i) { return texelFetch(viewTex, ivec2(i, v), 0); }

int cubeFace(vec3 d, out float s, out float t) {
  vec3 a = abs(d);
  if (a.x >= a.y && a.x >= a.z) { s = d.y / a.x; t = d.z / a.x; return d.x > 0.0 ? 0 : 1; }
  if (a.y >= a.z) { s = d.x / a.y; t = d.z / a.y; return d.y > 0.0 ? 2 : 3; }
  s = d.x / a.z; t = d.y / a.z; return d.z > 0.0 ? 4 : 5;
}

// The unnormalised weights of face f's views at d (views.c face_weights).
vec3 faceRaw(int f, vec3 d) {
  return vec3(dot(d, texelFetch(faceTex, ivec2(1, f), 0).xyz),
              dot(d, texelFetch(faceTex, ivec2(2, f), 0).xyz),
              dot(d, texelFetch(faceTex, ivec2(3, f), 0).xyz));
}

// views.c walk: from the cube map's start face across the edges to the face around d; -1
// when the walk leaves the faces (then every face is tried), -2 outside the covered region.
int walk(vec3 d) {
  float s, t;
  int n = startSide, face = cubeFace(d, s, t);
  int is = clamp(int((s + 1.0) * 0.5 * float(n)), 0, n - 1);
  int it = clamp(int((t + 1.0) * 0.5 * float(n)), 0, n - 1);
  int f = int(texelFetch(startTex, ivec2(is, face * n + it), 0).x);
  for (int step = 0; step < nFaces && f >= 0; step++) {
    vec3 r = faceRaw(f, d);
    float sum = r.x + r.y + r.z;
    if (!(sum > 0.0)) return -1;
    int m = r.y < r.x ? 1 : 0;
    if (r.z < r[m]) m = 2;
    if (r[m] >= -1e-6 * sum) return f;
    f = int(texelFetch(faceTex, ivec2(4, f), 0)[m]);
  }
  return f == -2 ? -2 : -1;
}

// views.c ap_views_weights: the face whose cone holds d, else the nearest boundary edge or view
void viewWeights(vec3 d, out ivec3 idx, out vec3 w) {
  int f = walk(d);
  for (int g = 0; g < nFaces && f == -1; g++) {
    vec3 r = faceRaw(g, d);
    if (r.x + r.y + r.z > 0.0 && r.x >= -1e-6 && r.y >= -1e-6 && r.z >= -1e-6) f = g;
  }
  if (f >= 0) {
    vec3 r = faceRaw(f, d);
    float s = r.x + r.y + r.z;
    idx = ivec3(texelFetch(faceTex, ivec2(0, f), 0).xyz);
    w = vec3(r.x > 0.0 ? r.x / s : 0.0, r.y > 0.0 ? r.y / s : 0.0, r.z > 0.0 ? r.z / s : 0.0);
    return;
  }
  float best = -2.0, len = length(d);
  idx = ivec3(0);
  w = vec3(1.0, 0.0, 0.0);
  for (int l = 0; l < nViews; l++) {
    vec4 dv = texelFetch(dirTex, ivec2(0, l), 0);
    if (dv.w == 0.0 && dot(d, dv.xyz) / len > best) {
      best = dot(d, dv.xyz) / len;
      idx = ivec3(l);
    }
  }
  for (int i = 0; i < nBnd; i++) {
    vec4 ab = texelFetch(bndTex, ivec2(0, i), 0);
    vec3 n = texelFetch(bndTex, ivec2(1, i), 0).xyz;
    vec3 p = d - dot(d, n) * n;
    float cs = length(p) / len;
    if (cs <= best) continue;
    int a = int(ab.x), b = int(ab.y);
    float wa = dot(cross(p, texelFetch(dirTex, ivec2(0, b), 0).xyz), n);
    float wb = dot(cross(texelFetch(dirTex, ivec2(0, a), 0).xyz, p), n);
    if (wa < 0.0 || wb < 0.0 || wa + wb <= 0.0) continue;
    best = cs;
    idx = ivec3(a, b, a);
    w = vec3(wa / (wa + wb), wb / (wa + wb), 0.0);
  }
}

// One bilinear tap of view vi: its mask at m (crop coordinates) and its depth at dd (depth
// layer coordinates) within tol of z.
float tap(int vi, ivec2 m, ivec2 dd, float z, float tol, ivec2 csz, ivec2 dsz) {
  if (any(lessThan(m, ivec2(0))) || any(greaterThanEqual(m, csz)) ||
      any(lessThan(dd, ivec2(0))) || any(greaterThanEqual(dd, dsz)))
    return 0.0;
  if (texelFetch(maskArr, ivec3(m, vi), 0).r == 0.0) return 0.0;
  return abs(texelFetch(depthArr, ivec3(dd, vi), 0).r - z) <= tol ? 1.0 : 0.0;
}

// render_px.c view_fade: a view's weight at cosine c to the surface.
float viewFade(float c) {
  return smoothstep(${FADE_LO}, ${FADE_HI}, c);
}

// render_px.c sample_view: adds wgt times view vi's weights at p (normal n, faded unless
// fade is false) to acc; returns the weight added.
float sampleView(int vi, vec3 p, vec3 n, bool fade, float wgt) {
  vec4 r0 = vt(vi, 0), r1 = vt(vi, 1), r2 = vt(vi, 2), in4 = vt(vi, 3), k4 = vt(vi, 4);
  vec4 m5 = vt(vi, 5), m6 = vt(vi, 6), cr = vt(vi, 7), m8 = vt(vi, 8);
  if (m5.w == 0.0) return 0.0; // not loaded yet
  vec3 x = vec3(r0.x * p.x + r0.y * p.y + r0.z * p.z + r0.w,
                r1.x * p.x + r1.y * p.y + r1.z * p.z + r1.w,
                r2.x * p.x + r2.y * p.y + r2.z * p.z + r2.w);
  if (x.z <= 0.0) return 0.0;
  if (fade) {
    vec3 rn = vec3(dot(r0.xyz, n), dot(r1.xyz, n), dot(r2.xyz, n));
    wgt *= viewFade(-dot(rn, x) / length(x));
    if (!(wgt > 0.0)) return 0.0;
  }
  float iz = 1.0 / x.z, xd = x.x * iz, yd = x.y * iz;
  float pu = in4.x * xd + in4.z, pv = in4.y * yd + in4.w;
  if (m8.w != 0.0) {
    float q2 = xd * xd + yd * yd, rad = 1.0 + q2 * (k4.x + q2 * (k4.y + q2 * m5.x));
    float xn = xd * rad + 2.0 * k4.z * xd * yd + k4.w * (q2 + 2.0 * xd * xd);
    yd = yd * rad + k4.z * (q2 + 2.0 * yd * yd) + 2.0 * k4.w * xd * yd;
    xd = xn;
  }
  float u = in4.x * xd + in4.z, v = in4.y * yd + in4.w;
  int x0 = int(floor(u)), y0 = int(floor(v));
  float a = u - float(x0), b = v - float(y0);
  float du = pu - a + m6.x + 0.5, dv = pv - b + m6.y + 0.5;
  if (x0 < 0 || y0 < 0 || x0 + 1 >= int(m5.y) || y0 + 1 >= int(m5.z) || du < 0.0 || dv < 0.0 ||
      int(du) + 1 >= int(m6.z) || int(dv) + 1 >= int(m6.w))
    return 0.0;
  ivec2 m = ivec2(x0, y0) - ivec2(cr.xy), csz = ivec2(cr.zw);
  ivec2 dd = ivec2(int(du), int(dv)) - ivec2(m8.xy), dsz = csz + 2 * ivec2(m6.xy);
  float tol = x.z * m8.z;
  vec4 bw = vec4(tap(vi, m, dd, x.z, tol, csz, dsz) * (1.0 - a) * (1.0 - b),
                 tap(vi, m + ivec2(1, 0), dd + ivec2(1, 0), x.z, tol, csz, dsz) * a * (1.0 - b),
                 tap(vi, m + ivec2(0, 1), dd + ivec2(0, 1), x.z, tol, csz, dsz) * (1.0 - a) * b,
                 tap(vi, m + ivec2(1, 1), dd + ivec2(1, 1), x.z, tol, csz, dsz) * a * b);
  float tw = bw.x + bw.y + bw.z + bw.w;
  if (!(tw > 1e-3)) return 0.0;
  bw /= tw;
  for (int gi = 0; gi < 8; gi++) {
    if (gi >= G) break;
    int layer = vi * G + gi;
    vec4 s = 255.0 * (bw.x * texelFetch(weightArr, ivec3(m, layer), 0) +
                      bw.y * texelFetch(weightArr, ivec3(m + ivec2(1, 0), layer), 0) +
                      bw.z * texelFetch(weightArr, ivec3(m + ivec2(0, 1), layer), 0) +
                      bw.w * texelFetch(weightArr, ivec3(m + ivec2(1, 1), layer), 0));
    vec4 sc = vt(vi, ${VIEW_TEXELS} + gi), off = vt(vi, ${VIEW_TEXELS} + G + gi);
    for (int c = 0; c < 4; c++)
      if (4 * gi + c < K) acc[4 * gi + c] += wgt * (off[c] + sc[c] * s[c]);
  }
  return wgt;
}


// render_px.c cube_sample + light_sum: the light term of unit l applied to acc.
vec3 pointTerm(vec3 l) {
  const int n = ${CUBE};
  float s, t;
  int face = cubeFace(l, s, t);
  float fs = clamp((s + 1.0) * 0.5 * float(n) - 0.5, 0.0, float(n - 1));
  float ft = clamp((t + 1.0) * 0.5 * float(n) - 0.5, 0.0, float(n - 1));
  int i0 = int(fs), j0 = int(ft), i1 = min(i0 + 1, n - 1), j1 = min(j0 + 1, n - 1);
  float a = fs - float(i0), b = ft - float(j0);
  vec3 q = vec3(0.0);
  for (int r = 0; r < 25; r++) {
    if (r >= lightTexels) break;
    vec4 v = (1.0 - b) * ((1.0 - a) * texelFetch(lightTex, ivec2(i0 * lightTexels + r, face * n + j0), 0) +
                          a * texelFetch(lightTex, ivec2(i1 * lightTexels + r, face * n + j0), 0)) +
             b * ((1.0 - a) * texelFetch(lightTex, ivec2(i0 * lightTexels + r, face * n + j1), 0) +
                  a * texelFetch(lightTex, ivec2(i1 * lightTexels + r, face * n + j1), 0));
    for (int c = 0; c < 4; c++) {
      int f = 4 * r + c, k = f / 3;
      if (k > K) break;
      q[f % 3] += (k == 0 ? 1.0 : acc[k - 1]) * v[c];
    }
  }
  return q;
}

vec3 constTerm() {
  vec3 q = vec3(lconst[0], lconst[1], lconst[2]);
  for (int k = 0; k < 32; k++) {
    if (k >= K) break;
    q += acc[k] * vec3(lconst[3 * k + 3], lconst[3 * k + 4], lconst[3 * k + 5]);
  }
  return q;
}

void main() {
  vec3 p = vPos, d = objDir;
  ivec3 idx;
  vec3 w;
  float ws = 0.0;
  for (int k = 0; k < 32; k++) acc[k] = 0.0;
  if (pixelMode != 0) d = normalize(camC - p);
  viewWeights(d, idx, w);
  // the normal (render_px.c surface_normal): the vertex normals', else the face's; towards
  // the camera
  vec3 n = dot(vNrm, vNrm) > 0.0 ? normalize(vNrm) : normalize(cross(dFdx(p), dFdy(p)));
  if (dot(n, camC - p) < 0.0) n = -n;
  for (int j = 0; j < 3; j++)
    if (w[j] > 0.0) ws += sampleView(idx[j], p, n, true, w[j]);
  for (int j = 0; j < 3; j++) // every view at grazing: unfaded
    if (!(ws > 0.0) && w[j] > 0.0) ws += sampleView(idx[j], p, n, false, w[j]);
  if (!(ws > 0.0)) discard;
  for (int k = 0; k < 32; k++) acc[k] /= ws;
  vec3 rgb;
  if (pointLight != 0) {
    vec3 l = lpos - p;
    float r2 = dot(l, l);
    rgb = lscale / r2 * pointTerm(l * inversesqrt(r2));
  } else {
    rgb = lscale * constTerm();
  }
  outColor = vec4(clamp(rgb * gain, 0.0, 1.0), 1.0);
}`;

  return {VS, MAIN_VS, DEPTH_FS, MAIN_FS};
}

// The BRDF model's environment mode (brdf.js): appearance/render_env.c in GLSL. BRDF_VS
// passes a triangle corner's uv and V_d, and the triangle (the mesh is drawn unindexed:
// gl_VertexID / 3); OBJECT_FS is shade_object, BACK_FS shade_ground or the map itself.
function gonioBrdfShaders() {
  const VS = gonioVertexShader(`layout(location = 1) in vec2 uvIn;
layout(location = 2) in float vdIn;
out vec2 vUv;
out float vVd;
flat out int vTri;`, `vUv = uvIn;
  vVd = vdIn;
  vTri = gl_VertexID / 3;`);

  const FULL_VS = `#version 300 es
void main() {
  gl_Position = vec4(float((gl_VertexID & 1) * 4 - 1), float((gl_VertexID & 2) * 2 - 1), 1.0, 1.0);
}`;

  // What both passes use: SH irradiance (prefilter.c ap_prefilter_irradiance), lat-long
  // bilinear taps (envmap.c ap_envmap_bilinear: x wraps, y clamps).
  const COMMON = `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2DArray;
const float PI = 3.14159265358979;
uniform vec3 sh[25];
uniform float shn[25];
uniform float scale, gain;
uniform vec3 camC;
uniform float groundR;
out vec4 outColor;

vec3 irradiance(vec3 d) {
  float y[25];
  float x = d.x, yy = d.y, z = d.z, c = 1.0, s = 0.0;
  for (int m = 0; m < 5; m++) {
    float q0 = 1.0, q1 = 0.0;
    if (m > 0) { float cn = c * x - s * yy; s = c * yy + s * x; c = cn; }
    for (int l = m; l < 5; l++) {
      float q = l == m ? 1.0 : l == m + 1 ? float(2 * m + 1) * z : 0.0;
      if (l > m + 1) q = (float(2 * l - 1) * z * q0 - float(l + m - 1) * q1) / float(l - m);
      q1 = q0; q0 = q;
      y[l * l + l + m] = shn[l * l + l + m] * q * c;
      if (m > 0) y[l * l + l - m] = shn[l * l + l + m] * q * s;
    }
  }
  vec3 e = vec3(0.0);
  for (int i = 0; i < 25; i++) e += sh[i] * y[i];
  return max(e, vec3(0.0));
}

// The four texels of a bilinear tap at (x, y) of a w x h lat-long image (x0, x1, y0, y1)
// and its fractions.
ivec4 latLongTap(float x, float y, int w, int h, out vec2 t) {
  float fx = floor(x), fy = floor(y);
  t = vec2(x - fx, y - fy);
  int xi = int(fx), x0 = xi - w * int(floor(float(xi) / float(w)));
  x0 = clamp(x0, 0, w - 1);
  return ivec4(x0, (x0 + 1) % w, clamp(int(fy), 0, h - 1), clamp(int(fy) + 1, 0, h - 1));
}
vec4 mix4(vec4 a, vec4 b, vec4 c, vec4 d, vec2 t) {
  return (1.0 - t.y) * ((1.0 - t.x) * a + t.x * b) + t.y * ((1.0 - t.x) * c + t.x * d);
}
`;

  // render_env.c shade_object, with spheres.c ap_ssdf and ap_sg_visible, prefilter.c
  // ap_prefilter_specular and render_env.c texel_at.
  const OBJECT_FS = COMMON + `
uniform highp sampler2D albTex, nrmTex, tanTex, pfNTex, sphTex, visTex;
uniform highp sampler2DArray pfArr;
uniform ivec2 atlasSize, pfSize;
uniform int cell, nTri, pairs, nSph, etas, angles;
uniform float pfA, pfCmin, sphCell;
in vec3 vPos;
in float vZ;
in vec2 vUv;
in float vVd;
flat in int vTri;

int texelTri(int x, int y) {
  int k = (y / cell) * (atlasSize.x / cell) + x / cell, lx = x % cell, ly = y % cell;
  int t = 2 * k + (lx + ly + 1 > cell ? 1 : 0);
  return t < nTri ? t : -1;
}

ivec2 texelAt(int t, vec2 uv) {
  int x = clamp(int(uv.x * float(atlasSize.x)), 0, atlasSize.x - 1);
  int y = clamp(int(uv.y * float(atlasSize.y)), 0, atlasSize.y - 1);
  for (int k = 0; k < 9; k++) {
    int xx = clamp(x + (k % 3 + 1) % 3 - 1, 0, atlasSize.x - 1);
    int yy = clamp(y + (k / 3 + 1) % 3 - 1, 0, atlasSize.y - 1);
    if (texelTri(xx, yy) == t) return ivec2(xx, yy);
  }
  return ivec2(x, y);
}

// render_env.c texel_taps + texel_blend: up to four texels of triangle t around uv, bilinear,
// masked ones (zero normal) and other triangles' left out; texelAt's alone when none is left.
void texelBlend(int t, vec2 uv, out vec4 alb, out vec4 nx, out float ay) {
  vec2 f = uv * vec2(atlasSize) - 0.5, b = floor(f), fr = f - b;
  float sum = 0.0;
  alb = vec4(0.0); nx = vec4(0.0); ay = 0.0;
  for (int k = 0; k < 4; k++) {
    ivec2 q = ivec2(b) + ivec2(k & 1, k >> 1);
    float w = ((k & 1) == 1 ? fr.x : 1.0 - fr.x) * ((k >> 1) == 1 ? fr.y : 1.0 - fr.y);
    if (q.x < 0 || q.y < 0 || q.x >= atlasSize.x || q.y >= atlasSize.y || w <= 0.0 ||
        texelTri(q.x, q.y) != t) continue;
    vec4 n4 = texelFetch(nrmTex, q, 0);
    if (dot(n4.xyz, n4.xyz) < 0.25) continue;
    alb += w * texelFetch(albTex, q, 0); nx += w * n4; ay += w * texelFetch(tanTex, q, 0).w;
    sum += w;
  }
  if (sum > 0.0) {
    alb /= sum; nx /= sum; ay /= sum;
  } else {
    ivec2 ti = texelAt(t, uv);
    alb = texelFetch(albTex, ti, 0); nx = texelFetch(nrmTex, ti, 0); ay = texelFetch(tanTex, ti, 0).w;
  }
  nx.xyz = normalize(nx.xyz);
}

vec3 specular(vec3 n, vec3 r) {
  float phi = atan(r.y, r.x), th = acos(clamp(r.z, -1.0, 1.0)), ws = 0.0;
  float x = phi * (0.5 / PI) * float(pfSize.x) - 0.5, y = th / PI * float(pfSize.y) - 0.5;
  vec2 t;
  ivec4 q = latLongTap(x, y, pfSize.x, pfSize.y, t);
  vec3 o = vec3(0.0);
  for (int k = 0; k < 256; k++) {
    if (k >= pairs) break;
    float c = abs(dot(n, texelFetch(pfNTex, ivec2(k, 0), 0).xyz));
    if (c < pfCmin) continue;
    float w = exp(pfA * log(c));
    vec4 px = mix4(texelFetch(pfArr, ivec3(q.x, q.z, k), 0), texelFetch(pfArr, ivec3(q.y, q.z, k), 0),
                   texelFetch(pfArr, ivec3(q.x, q.w, k), 0), texelFetch(pfArr, ivec3(q.y, q.w, k), 0), t);
    o += w * px.rgb * px.a;
    ws += w;
  }
  return ws > 0.0 ? o / ws : o;
}

float ssdf(vec3 v, vec3 n, vec3 zeta) {
  float best = PI / 2.0, cb = 0.0, sb = 1.0;
  for (int j = 0; j < 1024; j++) {
    if (j >= nSph) break;
    vec4 c = texelFetch(sphTex, ivec2(j, 0), 0);
    vec3 d = c.xyz - v;
    float r = c.w, L = length(d), dn = dot(d, n);
    if (L <= r || dn + r < 0.0) continue;
    if (dn < 0.0 && L - r < sphCell) continue;
    float cz = dot(d, zeta) / L, sbeta = r / L, cbeta = sqrt(1.0 - sbeta * sbeta);
    if ((sb < 0.0 && sbeta <= -sb) || cz <= cbeta * cb - sbeta * sb) continue;
    float val = acos(clamp(cz, -1.0, 1.0)) - asin(sbeta);
    if (val < best) { best = val; cb = cos(best); sb = sin(best); }
  }
  return best;
}

float sgVisible(float td, float eta) {
  float fe = log(max(eta, 0.5) / 0.5) / log(4e4) * float(etas - 1);
  float fa = (td + PI / 2.0) / PI * float(angles - 1);
  fe = clamp(fe, 0.0, float(etas) - 1.001);
  fa = clamp(fa, 0.0, float(angles) - 1.001);
  int e = int(fe), a = int(fa);
  return mix4(texelFetch(visTex, ivec2(a, e), 0), texelFetch(visTex, ivec2(a + 1, e), 0),
              texelFetch(visTex, ivec2(a, e + 1), 0), texelFetch(visTex, ivec2(a + 1, e + 1), 0),
              vec2(fa - float(a), fe - float(e))).r;
}

float planeSsdf(vec3 z) { return groundR > 0.0 ? asin(clamp(z.z, -1.0, 1.0)) : PI / 2.0; }

void main() {
  vec4 alb, nx;
  float ay;
  texelBlend(vTri, vUv, alb, nx, ay);
  vec3 n = nx.xyz, v = -normalize(vPos - camC);
  float ks = alb.a, nv = dot(n, v);
  vec3 o = (1.0 - ks) * alb.rgb / PI * irradiance(n) * vVd;
  if (ks > 0.0 && nv > 0.0) {
    vec3 rr = 2.0 * nv * n - v;
    float eta = 1.0 / (2.0 * nx.w * ay);
    float tp = asin(clamp(dot(rr, n), -1.0, 1.0));
    float td = min(min(ssdf(vPos, n, rr), planeSsdf(rr)), tp);
    o += ks * specular(n, rr) * sgVisible(td, eta) / max(sgVisible(tp, eta), 1e-3);
  }
  outColor = vec4(clamp(o * scale * gain, 0.0, 1.0), 1.0);
}`;

  // render_env.c shade_ground, else env_lookup, for the pixel's ray.
  const BACK_FS = COMMON + `
uniform highp sampler2D envTex, gvisTex;
uniform mat3 Rt;
uniform vec4 intr;
uniform float height, groundAlbedo;
uniform ivec2 envSize;
uniform int grid;

void main() {
  vec2 px = vec2(gl_FragCoord.x - 0.5, height - gl_FragCoord.y - 0.5);
  vec3 d = normalize(Rt * vec3((px.x - intr.z) / intr.x, (px.y - intr.w) / intr.y, 1.0)), o;
  float s = -camC.z / d.z;
  vec2 g = camC.xy + s * d.xy;
  if (groundR > 0.0 && d.z < 0.0 && camC.z > 0.0 && dot(g, g) <= groundR * groundR) {
    float m = float(grid - 1) - 0.001;
    vec2 f = clamp((g + groundR) / (2.0 * groundR) * float(grid - 1), 0.0, m);
    ivec2 i = ivec2(f);
    float v = mix4(texelFetch(gvisTex, i, 0), texelFetch(gvisTex, i + ivec2(1, 0), 0),
                   texelFetch(gvisTex, i + ivec2(0, 1), 0), texelFetch(gvisTex, i + ivec2(1, 1), 0),
                   f - vec2(i)).r;
    o = groundAlbedo / PI * irradiance(vec3(0.0, 0.0, 1.0)) * v;
  } else {
    float x = atan(d.y, d.x) * (0.5 / PI) * float(envSize.x) - 0.5;
    float y = acos(clamp(d.z, -1.0, 1.0)) / PI * float(envSize.y) - 0.5;
    vec2 t;
    ivec4 q = latLongTap(x, y, envSize.x, envSize.y, t);
    o = mix4(texelFetch(envTex, q.xz, 0), texelFetch(envTex, q.yz, 0), texelFetch(envTex, q.xw, 0),
             texelFetch(envTex, q.yw, 0), t).rgb;
  }
  outColor = vec4(clamp(o * scale * gain, 0.0, 1.0), 1.0);
}`;

  return {VS, FULL_VS, OBJECT_FS, BACK_FS};
}
