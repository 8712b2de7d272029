// brdf.js - the relighting viewer's environment mode with the BRDF model (docs/viewer.md):
// what appearance/render_env.c computes, for the scene the export made (webexport.h
// ap_web_env_scene): the map (or the ground) behind, the atlas mesh in front, shaded per
// pixel from its texel (albedo, ks, roughness, shading normal), the SH irradiance, the
// prefiltered maps and the sphere set's soft shadows (shaders.js gonioBrdfShaders). The data:
// data/brdf_mesh.js, brdf_texels.js, brdf_spheres.js and one brdf_env_NN.js per map.
'use strict';

// h: the viewer's GL helpers {gl, compile, cameraUniforms, pinholeUniforms, setNearest, shNorm}.
function gonioBrdf(h) {
  const gl = h.gl, S = gonioBrdfShaders();
  const progs = {depth: h.compile(S.VS, h.depthFS), object: h.compile(S.VS, S.OBJECT_FS),
                 back: h.compile(S.FULL_VS, S.BACK_FS)};
  const tex = {}, envs = [], shn = Float32Array.from(h.shNorm(5));
  let man = null, mesh = null;

  function texture(target, internal, w, h2, depth, format, type, data) {
    const t = gl.createTexture();
    gl.bindTexture(target, t);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    if (target === gl.TEXTURE_2D_ARRAY)
      gl.texImage3D(target, 0, internal, w, h2, depth, 0, format, type, data);
    else
      gl.texImage2D(target, 0, internal, w, h2, 0, format, type, data);
    h.setNearest(target);
    return t;
  }
  const tex2d = (internal, w, h2, format, type, data) =>
    texture(gl.TEXTURE_2D, internal, w, h2, 1, format, type, data);

  // The atlas mesh unindexed: per corner its position and uv (V_d comes per map).
  function uploadMesh(buf) {
    const nv = man.mesh.vertices, nt = man.mesh.triangles;
    const pos = new Float32Array(buf, 0, nv * 3), idx = new Uint32Array(buf, nv * 12, nt * 3);
    const uv = new Float32Array(buf, nv * 12 + nt * 12, nt * 6), p = new Float32Array(nt * 9);
    for (let i = 0; i < nt * 3; i++) p.set(pos.subarray(3 * idx[i], 3 * idx[i] + 3), 3 * i);
    mesh = {idx, count: nt * 3, vao: gl.createVertexArray()};
    gl.bindVertexArray(mesh.vao);
    [[p, 3], [uv, 2]].forEach(([data, n], loc) => {
      gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
      gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, n, gl.FLOAT, false, 0, 0);
    });
    gl.enableVertexAttribArray(2);
    gl.bindVertexArray(null);
  }

  function uploadTexels(buf) {
    const a = man.atlas, n = a.width * a.height;
    tex.alb = tex2d(gl.RGBA8, a.width, a.height, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(buf, 0, 4 * n));
    tex.nrm = tex2d(gl.RGBA16F, a.width, a.height, gl.RGBA, gl.HALF_FLOAT, new Uint16Array(buf, 4 * n, 4 * n));
    tex.tan = tex2d(gl.RGBA16F, a.width, a.height, gl.RGBA, gl.HALF_FLOAT, new Uint16Array(buf, 12 * n, 4 * n));
  }

  function uploadSpheres(buf) {
    const s = man.spheres, n = Math.max(1, s.count);
    const sph = new Float32Array(4 * n);
    sph.set(new Float32Array(buf, 0, 4 * s.count));
    tex.sph = tex2d(gl.RGBA32F, n, 1, gl.RGBA, gl.FLOAT, sph);
    tex.vis = tex2d(gl.R32F, s.angles, s.etas, gl.RED, gl.FLOAT,
                    new Float32Array(buf, 16 * s.count, s.angles * s.etas));
  }

  // Map e's data: the map, the prefiltered maps, V_d per corner, the ground's grid.
  function uploadEnv(e, buf) {
    const [mw, mh] = e.map, nm = 3 * mw * mh, np = 4 * e.pairs * e.width * e.height;
    const nv = man.mesh.vertices, g = e.ground.grid, half = new Uint16Array(buf);
    const vd = new Uint16Array(mesh.count);
    for (let i = 0; i < mesh.count; i++) vd[i] = half[nm + np + mesh.idx[i]];
    const nrm = new Float32Array(4 * e.pairs);
    for (let k = 0; k < e.pairs; k++) nrm.set(e.normals.slice(3 * k, 3 * k + 3), 4 * k);
    const vdBuf = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, vdBuf);
    gl.bufferData(gl.ARRAY_BUFFER, vd, gl.STATIC_DRAW);
    return {
      e, vdBuf,
      map: tex2d(gl.RGB16F, mw, mh, gl.RGB, gl.HALF_FLOAT, half.subarray(0, nm)),
      pf: texture(gl.TEXTURE_2D_ARRAY, gl.RGBA16F, e.width, e.height, e.pairs, gl.RGBA, gl.HALF_FLOAT,
                  half.subarray(nm, nm + np)),
      normals: tex2d(gl.RGBA32F, e.pairs, 1, gl.RGBA, gl.FLOAT, nrm),
      gvis: tex2d(gl.R16F, g, g, gl.RED, gl.HALF_FLOAT, half.subarray(nm + np + nv, nm + np + nv + g * g)),
    };
  }

  // Loads every BRDF chunk with loadChunk (the viewer's: checked, counted in the progress).
  async function load(m, loadChunk) {
    man = m;
    const [meshB, texB, sphB] = await Promise.all([loadChunk(man.mesh), loadChunk(man.texels),
                                                   loadChunk(man.spheres)]);
    uploadMesh(meshB);
    uploadTexels(texB);
    uploadSpheres(sphB);
    for (const e of man.envs) envs.push(uploadEnv(e, await loadChunk(e)));
  }

  function bind(u, units) {
    units.forEach(([name, target, t], i) => {
      gl.activeTexture(gl.TEXTURE0 + i);
      gl.bindTexture(target, t);
      gl.uniform1i(u[name], i);
    });
    gl.activeTexture(gl.TEXTURE0);
  }

  // The uniforms both passes share for map v, and the program in use.
  function common(pr, v, cam, gain) {
    gl.useProgram(pr.p);
    gl.uniform3fv(pr.u.sh, v.e.sh);
    gl.uniform1fv(pr.u.shn, shn);
    gl.uniform1f(pr.u.scale, man.response);
    gl.uniform1f(pr.u.gain, gain);
    gl.uniform3f(pr.u.camC, ...cam.eye);
    gl.uniform1f(pr.u.groundR, v.e.ground.radius);
  }

  function drawBack(v, cam, gain) {
    const pr = progs.back, u = pr.u;
    common(pr, v, cam, gain);
    gl.uniformMatrix3fv(u.Rt, false, cam.R);
    gl.uniform4f(u.intr, cam.fx, cam.fy, cam.cx, cam.cy);
    gl.uniform1f(u.height, cam.H);
    gl.uniform1f(u.groundAlbedo, v.e.ground.albedo);
    gl.uniform2i(u.envSize, v.e.map[0], v.e.map[1]);
    gl.uniform1i(u.grid, v.e.ground.grid);
    bind(u, [['envTex', gl.TEXTURE_2D, v.map], ['gvisTex', gl.TEXTURE_2D, v.gvis]]);
    gl.disable(gl.DEPTH_TEST);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
  }

  function drawMesh(pr, cam, v, near, far, depthFunc) {
    h.cameraUniforms(pr.u, cam.R, cam.t);
    h.pinholeUniforms(pr.u, cam.fx, cam.fy, cam.cx, cam.cy, cam.W, cam.H, near, far, true);
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(depthFunc);
    gl.disable(gl.CULL_FACE);
    gl.bindVertexArray(mesh.vao);
    gl.bindBuffer(gl.ARRAY_BUFFER, v.vdBuf);
    gl.vertexAttribPointer(2, 1, gl.HALF_FLOAT, false, 0, 0);
    gl.drawArrays(gl.TRIANGLES, 0, mesh.count);
    gl.bindVertexArray(null);
  }

  // A frame of map i for camera cam (the viewer's frameCamera), near/far its depth range.
  function draw(i, cam, gain, near, far) {
    const v = envs[i], pr = progs.object, u = pr.u, e = v.e;
    drawBack(v, cam, gain);
    gl.useProgram(progs.depth.p);
    gl.colorMask(false, false, false, false);
    drawMesh(progs.depth, cam, v, near, far, gl.LESS);
    gl.colorMask(true, true, true, true);
    common(pr, v, cam, gain);
    gl.uniform2i(u.atlasSize, man.atlas.width, man.atlas.height);
    gl.uniform2i(u.pfSize, e.width, e.height);
    gl.uniform1i(u.cell, man.atlas.cell);
    gl.uniform1i(u.nTri, man.mesh.triangles);
    gl.uniform1i(u.pairs, e.pairs);
    gl.uniform1i(u.nSph, man.spheres.count);
    gl.uniform1i(u.etas, man.spheres.etas);
    gl.uniform1i(u.angles, man.spheres.angles);
    gl.uniform1f(u.pfA, e.a);
    gl.uniform1f(u.pfCmin, e.cmin);
    gl.uniform1f(u.sphCell, man.spheres.cell);
    bind(u, [['albTex', gl.TEXTURE_2D, tex.alb], ['nrmTex', gl.TEXTURE_2D, tex.nrm],
             ['tanTex', gl.TEXTURE_2D, tex.tan], ['pfNTex', gl.TEXTURE_2D, v.normals],
             ['sphTex', gl.TEXTURE_2D, tex.sph], ['visTex', gl.TEXTURE_2D, tex.vis],
             ['pfArr', gl.TEXTURE_2D_ARRAY, v.pf]]);
    gl.depthMask(false);
    drawMesh(pr, cam, v, near, far, gl.EQUAL); // each visible pixel shaded once
    gl.depthMask(true);
  }

  // Bytes of every chunk, for the progress bar.
  const bytes = (m) => m.mesh.bytes + m.texels.bytes + m.spheres.bytes +
    m.envs.reduce((a, e) => a + e.bytes, 0);

  return {load, draw, bytes, ready: () => envs.length === (man ? man.envs.length : -1)};
}
