// surfsplat web viewer: draws the splats of data.js with the programs of shaders.js (the package's GLSL
// files composed for GLSL ES 3.00) in the passes of the desktop renderer (surfsplat.rendering.passes).
// No build step, no network: every input is a script loaded by the page.
//
// surfsplatViewer(root, SHADERS, DATA, options) builds the viewer inside the element root (its canvas,
// controls and HUD) and returns its state: the exported page calls it on its body (at the end of this
// file), the notebook widget (surfsplat.web.widget) on its output cell. options: params (the page's
// query and hash: camera, technique, ui, ...), url (keep the camera in the address), onCamera (called
// with the camera after a move).
function surfsplatViewer(root, SHADERS, DATA, options) {
  'use strict';
  options = options || {};
  var H = DATA.header;
  var params = options.params || {};
  if (!document.getElementById('surfsplat-style')) {
    var style = document.createElement('style');
    style.id = 'surfsplat-style';
    style.textContent = SURFSPLAT_CSS;
    document.head.appendChild(style);
  }
  root.classList.add('surfsplat-root');
  root.insertAdjacentHTML('beforeend', SURFSPLAT_MARKUP);
  function $(id) { return root.querySelector('#' + id); }

  // Attribute locations, bound before linking: one vertex array serves every splat program.
  var ATTRIBUTES = ['in_corner', 'in_position', 'in_normal', 'in_color', 'in_u', 'in_v',
                    'in_clip0', 'in_clip1', 'in_normal_field', 'in_nonplanar'];
  var NONPLANAR = 9;             // in_nonplanar: hybrid LiDAR drawing (shaders.py, HYBRID_POINTS)
  var NORMAL_FIELD = 8;          // in_normal_field: Phong splats' (alpha, beta) (Botsch 2004, eq. 2)
  var NO_DEPTH = 1e37;           // shaders.NO_DEPTH: the visibility target's clear value
  var SIDE_UNIT = 2;             // passes.SIDE_TEXTURE_UNIT
  var COVER_UNIT = 3;            // passes.COVER_TEXTURE_UNIT: the splats' pixel coverage (edge coverage)
  var EDL_COLOR_UNIT = 4, EDL_DEPTH_UNIT = 5;
  var NORM_COLOR_UNIT = 0, NORM_DEPTH_UNIT = 1, NORM_Z_UNIT = 2;   // passes.NORM_*_UNIT: the fill pass's inputs

  var state = {
    technique: H.technique, background: H.background.slice(), edl: H.technique === 'points',
    camera: null, frameMs: 0, frames: 0, timings: {}, splats: H.count, errors: [], ready: false, firstFrameMs: null,
    colorBy: 'own colours',
    ui: true, width: 0, height: 0, supersample: 1
  };
  // one full-quality frame drawn now; its time in milliseconds (the benchmark's)
  state.redraw = function () { render(); return state.frameMs; };
  // move the view to a camera {eye, target, up, fov} (world units; the notebook widget's camera)
  state.setCamera = function (c) {
    state.camera = {eye: c.eye.slice(), target: c.target.slice(), up: c.up.slice(), fov: c.fov || H.fov};
    state.moved = true;
    request();
  };

  function fail(text) {
    state.errors.push(text);
    var box = $('message');
    box.textContent = text;
    box.style.display = 'block';
    console.error(text);
  }

  // ---- decoding: the twin of surfsplat/web/format.py --------------------------------------------
  function bytes(b64) {
    // the native decoder where the browser has it (Chromium 140+, Firefox 133+, Safari 18.2+): 10x the loop
    if (Uint8Array.fromBase64) return Uint8Array.fromBase64(b64);
    var bin = atob(b64), out = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; ++i) out[i] = bin.charCodeAt(i);
    return out;
  }

  function u16(b64) { var b = bytes(b64); return new Uint16Array(b.buffer, b.byteOffset, b.length / 2); }

  function octahedral(qn, i) {   // format.octahedral_decode of code i
    var x = -1 + qn[2 * i] / 65534 * 2, y = -1 + qn[2 * i + 1] / 65534 * 2;   // format.OCT_LEVELS
    var z = 1 - Math.abs(x) - Math.abs(y), t = Math.max(-z, 0);
    x -= x >= 0 ? t : -t;
    y -= y >= 0 ? t : -t;
    var len = Math.sqrt(x * x + y * y + z * z);
    return [x / len, y / len, z / len];
  }

  // A page's splats (H, DATA.streams) or a streamed cell's. With a step (the decimated first preview) only
  // splats 0, step, 2 step, ... and only what the points program reads (position, normal, colour, u, v),
  // their axes grown by grow; codes, where given, memoizes the streams' bytes for the full decode after it.
  function decode(hd, s, step, grow, codes) {
    var H = hd, n = H.count;
    step = step || 1; grow = grow || 1; codes = codes || {};
    function code(key) { if (!(key in codes)) codes[key] = bytes(s[key]); return codes[key]; }
    function code16(key) { var b = code(key); return new Uint16Array(b.buffer, b.byteOffset, b.length / 2); }
    var qp = code16('position'), qn = code16('normal'), qa = code16('angle'), qr = code16('radii'), qc = code('color');
    var m = Math.ceil(n / step);
    var pos = new Float32Array(3 * m), nrm = new Float32Array(3 * m), u = new Float32Array(3 * m),
        v = new Float32Array(3 * m);
    var lo = H.lo, hi = H.hi, U16 = 65535;   // format.U16
    var w0 = hi[0] - lo[0], w1 = hi[1] - lo[1], w2 = hi[2] - lo[2];
    // format.decode_positions: with position_fine, 24-bit codes (position the high 16 bits, position_fine the low 8)
    var qf = s.position_fine ? code('position_fine') : null, PL = qf ? 16777215 : U16;   // format.FINE_LEVELS
    function coord(q) { return qf ? qp[q] * 256 + qf[q] : qp[q]; }
    var l0 = H.log_radius[0], lw = H.log_radius[1] - H.log_radius[0];
    for (var r = 0; r < m; ++r) {
      var i = r * step, k = 3 * r, q = 3 * i;
      pos[k] = lo[0] + coord(q) / PL * w0;
      pos[k + 1] = lo[1] + coord(q + 1) / PL * w1;
      pos[k + 2] = lo[2] + coord(q + 2) / PL * w2;
      var dn = octahedral(qn, i), x = dn[0], y = dn[1], z = dn[2];
      nrm[k] = x; nrm[k + 1] = y; nrm[k + 2] = z;
      // tangent_basis (Duff et al. 2017)
      var sign = z >= 0 ? 1 : -1, a = -1 / (sign + z), b = x * y * a;
      var b1x = 1 + sign * x * x * a, b1y = sign * b, b1z = -sign * x;
      var b2x = b, b2y = sign + y * y * a, b2z = -y;
      var ang = qa[i] * (Math.PI / 65536), c = Math.cos(ang), sn = Math.sin(ang);
      var dx = c * b1x + sn * b2x, dy = c * b1y + sn * b2y, dz = c * b1z + sn * b2z;
      var ru = grow * Math.pow(2, l0 + qr[2 * i] / U16 * lw), rv = grow * Math.pow(2, l0 + qr[2 * i + 1] / U16 * lw);
      u[k] = dx * ru; u[k + 1] = dy * ru; u[k + 2] = dz * ru;
      v[k] = (y * dz - z * dy) * rv; v[k + 1] = (z * dx - x * dz) * rv; v[k + 2] = (x * dy - y * dx) * rv;
    }
    if (s.shading) {   // Phong splats (page.encoded): the normal codes the plane; the shading normal apart
      var qs = code16('shading');
      for (r = 0; r < m; ++r) { var sh = octahedral(qs, r * step); nrm[3 * r] = sh[0]; nrm[3 * r + 1] = sh[1]; nrm[3 * r + 2] = sh[2]; }
    }
    var color = qc;
    if (step > 1) {
      color = new Uint8Array(3 * m);
      for (r = 0; r < m; ++r) { color[3 * r] = qc[3 * r * step]; color[3 * r + 1] = qc[3 * r * step + 1]; color[3 * r + 2] = qc[3 * r * step + 2]; }
    }
    var out = {position: pos, normal: nrm, u: u, v: v, color: color, count: m};
    if (step > 1) return out;
    if (s.normal_field) out.normalField = u16(s.normal_field);   // (alpha, beta) as float16, flipped with the axes
    if (s.clip) {   // format.encode_clip_lines: the rows that cut and their two lines, float16 (zero: no cut)
      var rb = bytes(s.clip_rows), rows = new Uint32Array(rb.buffer, rb.byteOffset, rb.length / 4), lines = u16(s.clip);
      var c0 = new Uint16Array(3 * n), c1 = new Uint16Array(3 * n);
      for (i = 0; i < rows.length; ++i) {
        for (var j = 0; j < 3; ++j) { c0[3 * rows[i] + j] = lines[6 * i + j]; c1[3 * rows[i] + j] = lines[6 * i + 3 + j]; }
      }
      out.clip0 = c0; out.clip1 = c1;
    }
    if (s.nonplanar) {   // page.hybrid_stream: one bit a splat, little bit order (np.packbits)
      var bits = bytes(s.nonplanar), flags = new Uint8Array(n);
      for (i = 0; i < n; ++i) flags[i] = (bits[i >> 3] >> (i & 7)) & 1;
      out.nonplanar = flags;
    }
    return out;
  }

  // ---- small float64 vector helpers ---------------------------------------------------------------
  function sub(a, b) { return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]; }
  function add(a, b) { return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]; }
  function scale(a, s) { return [a[0] * s, a[1] * s, a[2] * s]; }
  function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
  function cross(a, b) { return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]; }
  function norm(a) { return Math.sqrt(dot(a, a)); }
  function unit(a) { return scale(a, 1 / norm(a)); }
  function rotate(v, axis, angle) {   // Rodrigues, axis unit
    var c = Math.cos(angle), s = Math.sin(angle);
    return add(add(scale(v, c), scale(cross(axis, v), s)), scale(axis, dot(axis, v) * (1 - c)));
  }

  // Camera.view_matrix (gluLookAt) of eye/target/up given relative to the splats' origin: rows.
  function viewRows(eye, target, up) {
    var f = unit(sub(target, eye)), s = unit(cross(f, up)), u = cross(s, f);
    return [s, u, scale(f, -1), [-dot(s, eye), -dot(u, eye), dot(f, eye)]];
  }

  // Camera.with_clip_from_bounds of the splats' bounds grown by their largest radius (framing.clipped_to).
  function nearFar(eye, target, up) {
    var r = viewRows(eye, target, up), m = H.max_radius;
    var lo = sub(H.bounds[0], [m, m, m]), hi = add(H.bounds[1], [m, m, m]);
    var dmin = Infinity, dmax = -Infinity;
    for (var i = 0; i < 8; ++i) {
      var c = [(i & 1) ? hi[0] : lo[0], (i & 2) ? hi[1] : lo[1], (i & 4) ? hi[2] : lo[2]];
      var d = -(dot(r[2], c) + r[3][2]);
      dmin = Math.min(dmin, d); dmax = Math.max(dmax, d);
    }
    var diag = norm(sub(hi, lo)) || 1;
    var far = Math.max(dmax * 1.01, diag * 1e-3);
    var near = Math.max(dmin * 0.99, far * 1e-4, diag * 1e-4);
    return [Math.min(near, far * 0.5), far];
  }

  // surfsplat.web.framing.camera_from_frame: fit_points of the exported hulls at this size.
  function centering(hull, dist, m) {
    var lo = Infinity, hi = -Infinity, i;
    for (i = 0; i < hull.length; ++i) { lo = Math.min(lo, hull[i][0]); hi = Math.max(hi, hull[i][0]); }
    lo -= m; hi += m;
    for (var step = 0; step < 60; ++step) {
      var c = 0.5 * (lo + hi), big = -Infinity, small = Infinity;
      for (i = 0; i < hull.length; ++i) {
        var depth = dist - hull[i][1];
        big = Math.max(big, (hull[i][0] + m - c) / depth);
        small = Math.min(small, (hull[i][0] - m - c) / depth);
      }
      if (big + small > 0) lo = c; else hi = c;
    }
    return 0.5 * (lo + hi);
  }

  function defaultCamera(width, height) {
    var F = H.fit, m = F.margin, fov = H.fov, fill = 0.9;
    var ty = fill * Math.tan(fov * Math.PI / 360), tx = ty * width / height;
    var hulls = [F.hull_x, F.hull_y], ts = [tx, ty], offsets = [], distances = [];
    for (var k = 0; k < 2; ++k) {
      var a = -Infinity, b = -Infinity, hull = hulls[k], t = ts[k];
      for (var i = 0; i < hull.length; ++i) {
        a = Math.max(a, hull[i][1] + (hull[i][0] + m) / t);
        b = Math.max(b, hull[i][1] + (m - hull[i][0]) / t);
      }
      offsets.push(0.5 * t * (a - b));
      distances.push(0.5 * (a + b));
    }
    var dist = Math.max(Math.max(distances[0], distances[1]), F.zmax + m + 1e-3 * F.extent);
    for (k = 0; k < 2; ++k) if (distances[k] < dist) offsets[k] = centering(hulls[k], dist, m);
    var target = add(add(F.center, scale(F.right, offsets[0])), scale(F.screen_up, offsets[1]));
    return {eye: add(target, scale(F.direction, dist)), target: target, up: F.up.slice(), fov: fov};
  }

  // ---- GL setup -------------------------------------------------------------------------------------
  var canvas = $('view');
  var gl = canvas.getContext('webgl2', {antialias: false, alpha: false, depth: false, stencil: false,
                                        preserveDrawingBuffer: true, premultipliedAlpha: false});
  if (!gl) { fail('This browser has no WebGL2: the viewer needs it.'); return state; }
  if (!gl.getExtension('EXT_color_buffer_float')) { fail('WebGL2 without EXT_color_buffer_float: float targets are needed.'); return state; }
  var floatBlend = !!gl.getExtension('EXT_float_blend');

  function compile(type, text, name) {
    var sh = gl.createShader(type);
    gl.shaderSource(sh, text);
    gl.compileShader(sh);
    if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) {
      throw new Error('shader ' + name + ' failed to compile: ' + translate(gl.getShaderInfoLog(sh), SHADERS.programs[name].files));
    }
    return sh;
  }

  // shaders.translate_log: a position "S:L" with L = k * 10000 + line names file k's line.
  function translate(log, files) {
    return String(log).replace(/(\d+):(\d+)/g, function (all, src, line) {
      var k = Math.floor(line / 10000), local = line % 10000;
      return (k > 0 && k < files.length) ? files[k] + ':' + local : all;
    });
  }

  // Programs are compiled and linked on first use (a frame of one technique needs 3-6 of the 29): the first
  // frame waits for its own programs only. state.compileAll() builds every one (the tests: each links here).
  var programs = {}, linked = {};
  function program(name) {
    if (!(name in programs)) {
      if (!(name in SHADERS.programs)) throw new Error('no program ' + name + ' in shaders.js');
      var start = performance.now();
      programs[name] = build(name);
      state.programs = Object.keys(programs);
      state.timings.compile = (state.timings.compile || 0) + performance.now() - start;
    }
    return programs[name];
  }
  state.programs = [];   // the programs compiled and linked so far
  state.compileAll = function () {
    try { for (var name in SHADERS.programs) program(name); } catch (e) { fail(String(e && e.message || e)); }
    return state.programs;
  };
  function build(name) {   // programs of the same sources (phong's and blend's visibility) are linked once
    var p = SHADERS.programs[name], key = p.vertex + '\u0000' + p.fragment;
    if (!(key in linked)) linked[key] = link(name, p);
    return linked[key];
  }
  function link(name, p) {
    var prog = gl.createProgram();
    gl.attachShader(prog, compile(gl.VERTEX_SHADER, p.vertex, name));
    gl.attachShader(prog, compile(gl.FRAGMENT_SHADER, p.fragment, name));
    for (var i = 0; i < ATTRIBUTES.length; ++i) gl.bindAttribLocation(prog, i, ATTRIBUTES[i]);
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error('program ' + name + ' failed to link: ' + gl.getProgramInfoLog(prog));
    for (var block in SHADERS.blocks) {
      var index = gl.getUniformBlockIndex(prog, block);
      if (index !== gl.INVALID_INDEX) gl.uniformBlockBinding(prog, index, SHADERS.blocks[block].binding);
    }
    var uniforms = {}, count = gl.getProgramParameter(prog, gl.ACTIVE_UNIFORMS);
    for (i = 0; i < count; ++i) {
      var info = gl.getActiveUniform(prog, i), key = info.name.replace(/\[0\]$/, '');
      var loc = gl.getUniformLocation(prog, info.name);
      if (loc) uniforms[key] = {loc: loc, type: info.type, size: info.size};
    }
    return {program: prog, uniforms: uniforms};
  }

  function setUniforms(p, values) {
    gl.useProgram(p.program);
    for (var key in values) {
      var u = p.uniforms[key];
      if (!u) continue;   // declared but not active in this program (the compiler dropped it)
      var v = values[key], arr = Array.isArray(v) ? v : [v];
      switch (u.type) {
        case gl.FLOAT: gl.uniform1fv(u.loc, arr); break;
        case gl.FLOAT_VEC2: gl.uniform2fv(u.loc, arr); break;
        case gl.FLOAT_VEC3: gl.uniform3fv(u.loc, arr); break;
        case gl.FLOAT_VEC4: gl.uniform4fv(u.loc, arr); break;
        case gl.INT_VEC2: gl.uniform2iv(u.loc, arr); break;
        case gl.BOOL: case gl.INT: case gl.SAMPLER_2D: case gl.UNSIGNED_INT_SAMPLER_2D:
          gl.uniform1iv(u.loc, arr.map(Number)); break;
        default: throw new Error('uniform ' + key + ' of an unexpected type ' + u.type);
      }
    }
  }

  // The frame's std140 blocks (uniform_blocks.py lays them out from the same declarations).
  var blocks = {};
  for (var name in SHADERS.blocks) {
    var layout = SHADERS.blocks[name], buffer = gl.createBuffer(), data = new ArrayBuffer(layout.size);
    gl.bindBuffer(gl.UNIFORM_BUFFER, buffer);
    gl.bufferData(gl.UNIFORM_BUFFER, layout.size, gl.DYNAMIC_DRAW);
    gl.bindBufferBase(gl.UNIFORM_BUFFER, layout.binding, buffer);
    blocks[name] = {layout: layout, buffer: buffer, data: data, f32: new Float32Array(data), i32: new Int32Array(data)};
  }

  function writeBlocks(values) {
    for (var name in blocks) {
      var b = blocks[name];
      b.layout.members.forEach(function (m) {
        if (!(m.name in values)) throw new Error('uniform block ' + name + ' needs ' + m.name);
        var v = values[m.name], flat = [].concat.apply([], Array.isArray(v) ? v.map(function (x) { return Array.isArray(x) ? x : [x]; }) : [[v]]);
        var at = m.offset / 4;
        if (m.type === 'int' || m.type === 'bool' || m.type === 'uint') { b.i32[at] = Number(flat[0]); return; }
        var width = {float: 1, vec2: 2, vec3: 3, vec4: 4, mat4: 16}[m.type];
        if (m.length === null || m.length === undefined) { for (var i = 0; i < flat.length; ++i) b.f32[at + i] = flat[i]; return; }
        for (var row = 0; row < m.length; ++row) for (var c = 0; c < width; ++c) b.f32[at + 4 * row + c] = flat[row * width + c];
      });
      gl.bindBuffer(gl.UNIFORM_BUFFER, b.buffer);
      gl.bufferSubData(gl.UNIFORM_BUFFER, 0, b.data);
    }
  }

  // ---- splats -------------------------------------------------------------------------------------
  // Small splats are drawn as GL_POINTS, one vertex each (POINT_PRIMITIVE); the largest (first: export.py
  // orders them by radius class) as quads of two triangles. No instancing: SwiftShader, Chromium's CPU WebGL,
  // runs an instanced draw one instance at a time (a million instances took a minute a frame).
  var QUAD_CAPACITY = 65536;   // splats that can be drawn as quads (their vertices are 6 copies)
  var CORNERS = [-1, -1, 1, -1, -1, 1, -1, 1, 1, -1, 1, 1];
  var splats, pointsVao = gl.createVertexArray(), quadsVao = gl.createVertexArray(), empty = gl.createVertexArray();
  var quadCount = 0, maxPoint = gl.getParameter(gl.ALIASED_POINT_SIZE_RANGE)[1];
  function attribute(index, array, size, type, normalized) {
    var buf = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.bufferData(gl.ARRAY_BUFFER, array, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(index);
    gl.vertexAttribPointer(index, size, type, normalized, 0, 0);
    return buf;
  }
  function repeated(array, width, count, Kind) {   // each of the first count rows 6 times
    var out = new Kind(6 * width * count);
    for (var i = 0; i < count; ++i) for (var r = 0; r < 6; ++r) for (var c = 0; c < width; ++c) out[(6 * i + r) * width + c] = array[i * width + c];
    return out;
  }
  // the attributes every splat has (position, normal, colour, u, v) into the bound vertex array: their buffers
  function splatAttributes(decoded) {
    return [attribute(1, decoded.position, 3, gl.FLOAT, false), attribute(2, decoded.normal, 3, gl.FLOAT, false),
            attribute(3, decoded.color, 3, gl.UNSIGNED_BYTE, true), attribute(4, decoded.u, 3, gl.FLOAT, false),
            attribute(5, decoded.v, 3, gl.FLOAT, false)];
  }
  // no vertex array bound, and the constant values of the attributes a points vertex array leaves unbound
  function unbindSplats() {
    gl.bindVertexArray(null);
    gl.vertexAttrib2f(0, 0, 0);   // a point has no corner
    for (var j = 6; j < ATTRIBUTES.length; ++j) gl.vertexAttrib4f(j, 0, 0, 0, 0);   // no clip lines, no normal field
  }
  function upload(decoded) {
    gl.bindVertexArray(pointsVao);
    colorBuffers = [splatAttributes(decoded)[2]];
    if (decoded.nonplanar) attribute(NONPLANAR, decoded.nonplanar, 1, gl.UNSIGNED_BYTE, false);
    if (decoded.normalField) attribute(NORMAL_FIELD, decoded.normalField, 2, gl.HALF_FLOAT, false);
    if (decoded.clip0) {   // in_clip0, in_clip1 (Zwicker 2004, sec. 5)
      attribute(6, decoded.clip0, 3, gl.HALF_FLOAT, false);
      attribute(7, decoded.clip1, 3, gl.HALF_FLOAT, false);
    }
    if (H.lod) {   // the drawn entries: an index list chosen per view (selectCut)
      elements = gl.createBuffer();
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, elements);
      unbindSplats();
      return;
    }
    quadCount = Math.min(H.count, QUAD_CAPACITY);
    gl.bindVertexArray(quadsVao);
    var corners = new Float32Array(12 * quadCount);
    for (var i = 0; i < quadCount; ++i) corners.set(CORNERS, 12 * i);
    attribute(0, corners, 2, gl.FLOAT, false);
    attribute(1, repeated(decoded.position, 3, quadCount, Float32Array), 3, gl.FLOAT, false);
    attribute(2, repeated(decoded.normal, 3, quadCount, Float32Array), 3, gl.FLOAT, false);
    colorBuffers.push(attribute(3, repeated(decoded.color, 3, quadCount, Uint8Array), 3, gl.UNSIGNED_BYTE, true));
    attribute(4, repeated(decoded.u, 3, quadCount, Float32Array), 3, gl.FLOAT, false);
    attribute(5, repeated(decoded.v, 3, quadCount, Float32Array), 3, gl.FLOAT, false);
    if (decoded.nonplanar) attribute(NONPLANAR, repeated(decoded.nonplanar, 1, quadCount, Uint8Array), 1, gl.UNSIGNED_BYTE, false);
    if (decoded.normalField) attribute(NORMAL_FIELD, repeated(decoded.normalField, 2, quadCount, Uint16Array), 2, gl.HALF_FLOAT, false);
    if (decoded.clip0) {
      attribute(6, repeated(decoded.clip0, 3, quadCount, Uint16Array), 3, gl.HALF_FLOAT, false);
      attribute(7, repeated(decoded.clip1, 3, quadCount, Uint16Array), 3, gl.HALF_FLOAT, false);
    }
    unbindSplats();
  }

  // The decimated first preview of a large page: every step-th splat (a spatially even subset: each radius
  // class is in Morton order, web_order), drawn as points with its axes grown by sqrt(step) so that the
  // surface stays covered, before the other splats are decoded; then the full-quality frame.
  var PREVIEW_SPLATS = 131072, preview = null, pageCodes = null;
  function previewStep() {
    if (H.lod || (params.color && params.color !== OWN_COLORS)) return 1;
    // every preview point within the largest GL_POINTS point (points.vert clamps its diameter)
    if (Math.min(maxPoint, 1024) < H.uniforms.points.u_point_size[1] * state.supersample + 2) return 1;
    return Math.ceil(H.count / previewSplats());
  }
  function previewSplats() { return Number(params.preview) >= 1 ? Math.floor(Number(params.preview)) : PREVIEW_SPLATS; }   // ?preview=N
  function uploadPreview(d, step) {
    var vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    var buffers = splatAttributes(d);
    unbindSplats();
    return {vao: vao, buffers: buffers, count: d.count, step: step};
  }
  // the page's splats decoded and uploaded (after the preview where there is one)
  function loadSplats() {
    var start = performance.now();
    splats = decode(H, DATA.streams, 1, 1, pageCodes || {});
    pageCodes = null;
    if (H.lod) {
      tree = readTree(DATA.streams);
      state.budget = Number(params.budget) >= 1 ? Math.floor(Number(params.budget)) : H.lod.budget;
    }
    state.timings.decode = performance.now() - start;
    start = performance.now();
    upload(splats);
    if (H.lod) {
      topTree = {T: tree, M: H.lod.nodes, offsets: H.lod.level_offsets, vao: pointsVao, elements: elements, drawn: 0};
      if (H.lod.streamed) startStreaming();
    }
    state.timings.upload = performance.now() - start;
    if (preview) {
      preview.buffers.forEach(function (b) { gl.deleteBuffer(b); });
      gl.deleteVertexArray(preview.vao);
      preview = null;
      if (state.colorBy !== OWN_COLORS) setColorBy(state.colorBy);
    }
  }

  // ---- colour by attribute (surfsplat.web.colors): the desktop viewer's C key --------------------------
  // A mode maps each splat's value (an exported attribute, or the elevation of its decoded position along
  // the up axis) to t = (value - lo) / (hi - lo) in [0, 1] and takes entry min(floor(256 t), 255) of its
  // colormap's table (matplotlib's indexing); the ASPRS palette is indexed by the class code.
  var colorBuffers = [], colorTables = {}, OWN_COLORS = 'own colours';
  function colorModes() { return [OWN_COLORS].concat((H.color ? H.color.modes : []).map(function (m) { return m.name; })); }
  function attributeValues(info, b64) {
    var b = bytes(b64), codes = info.type === 'u8' ? b : new Uint16Array(b.buffer, b.byteOffset, b.length / 2);
    var out = new Float64Array(codes.length);
    for (var i = 0; i < codes.length; ++i) out[i] = info.offset + codes[i] * info.scale;
    return out;
  }
  // the colours of splats (the page's, or a streamed cell's: its header, streams, decoded positions and
  // own colours) coloured by the mode name
  function modeColors(name, hd, streams, position, own) {
    if (name === OWN_COLORS) return own;
    var m = null;
    H.color.modes.forEach(function (x) { if (x.name === name) m = x; });
    if (!m) throw new Error('no colouring ' + name + ' on this page');
    var n = hd.count, values, i;
    if (m.up) {
      values = new Float64Array(n);
      for (i = 0; i < n; ++i) values[i] = position[3 * i] * m.up[0] + position[3 * i + 1] * m.up[1] + position[3 * i + 2] * m.up[2];
    } else values = attributeValues((hd.color || hd).attributes[m.attribute], streams['attr_' + m.attribute]);
    if (!(m.colormap in colorTables)) colorTables[m.colormap] = bytes(H.color.tables[m.colormap]);
    var table = colorTables[m.colormap], out = new Uint8Array(3 * n), lo = m.range[0], w = m.range[1] - m.range[0];
    for (i = 0; i < n; ++i) {
      var v = values[i], k;
      if (m.colormap === 'asprs') k = (v >= 0 && v <= 255 && v === Math.round(v)) ? v : 255;
      else k = Math.min(Math.floor(Math.min(1, Math.max(0, (v - lo) / w)) * 256), 255);
      out[3 * i] = table[3 * k]; out[3 * i + 1] = table[3 * k + 1]; out[3 * i + 2] = table[3 * k + 2];
    }
    return out;
  }
  function recolorCell(c) {   // a loaded cell in the page's colouring
    var x = c.tree;
    gl.bindBuffer(gl.ARRAY_BUFFER, x.buffers[2]);
    gl.bufferData(gl.ARRAY_BUFFER, modeColors(state.colorBy, x.data.header, x.data.streams, x.position, x.color),
                  gl.STATIC_DRAW);
  }
  function setColorBy(name) {
    if (colorModes().indexOf(name) < 0) return;
    state.colorBy = name;
    if (preview) { syncControls(); return; }   // applied once the splats are loaded
    var colors = modeColors(name, H, DATA.streams, splats.position, splats.color);
    gl.bindBuffer(gl.ARRAY_BUFFER, colorBuffers[0]);
    gl.bufferData(gl.ARRAY_BUFFER, colors, gl.STATIC_DRAW);
    if (colorBuffers.length > 1) {
      gl.bindBuffer(gl.ARRAY_BUFFER, colorBuffers[1]);
      gl.bufferData(gl.ARRAY_BUFFER, repeated(colors, 3, quadCount, Uint8Array), gl.STATIC_DRAW);
    }
    if (cells) cells.forEach(function (c) { if (c.tree) recolorCell(c); });
    syncControls();
    saveUrl();
    request();
  }

  // passes.point_scale and point_radius: the largest radius drawn as a point in this frame (model units).
  function pointRadius(values, technique) {
    var fp = H.footprints[technique], px = Math.min(maxPoint, 1024), f = values.u_focal;
    var w = values.u_viewport[0], h = values.u_viewport[1];
    var stretch = Math.hypot(1, Math.hypot(w, h) / (2 * f)), side = px - 1, scaleR;
    if (!fp.footprint) return 0;
    if (fp.footprint === 'adaptive') {
      if (fp.min_point_px * values.u_supersample > side) return 0;
      scaleR = side / (2 * f * stretch);
    } else {
      if (fp.footprint === 'filtered_disk') {
        var u = H.uniforms[technique];
        side -= 2 * Math.sqrt(2 * u.u_cutoff[0] * u.u_prefilter[0]);
      }
      scaleR = Math.max(side, 0) / (2 * Math.SQRT2 * f * stretch);
    }
    var m = H.max_radius, lo = sub(sub(H.bounds[0], H.origin), [m, m, m]), hi = add(sub(H.bounds[1], H.origin), [m, m, m]);
    var nearest = Infinity, view = values.u_view;
    for (var i = 0; i < 8; ++i) {
      var c = [(i & 1) ? hi[0] : lo[0], (i & 2) ? hi[1] : lo[1], (i & 4) ? hi[2] : lo[2]];
      nearest = Math.min(nearest, -(view[2] * c[0] + view[6] * c[1] + view[10] * c[2] + view[14]));
    }
    return scaleR * Math.max(values.u_near_far[0], nearest);
  }

  // GpuSplats.quad_count: the splats of every radius class whose largest radius exceeds r (a prefix).
  function largerThan(r) {
    var big = 0;
    while (big < H.class_radius.length && H.class_radius[big] > r) ++big;
    return big === H.class_radius.length ? H.count : H.class_start[big];
  }

  // ---- level of detail in the browser (surfsplat.web.tree): the cut of hierarchy.lod.select -----
  var tree = null, elements = null;
  function i32(b64) { var b = bytes(b64); return new Int32Array(b.buffer, b.byteOffset, b.length / 4); }
  function f32(b64) { var b = bytes(b64); return new Float32Array(b.buffer, b.byteOffset, b.length / 4); }
  function readTree(s) {
    return {childStart: i32(s.child_start), childCount: i32(s.child_count), pointStart: i32(s.point_start),
            pointCount: i32(s.point_count), center: f32(s.center), radius: f32(s.radius), extent: f32(s.extent),
            sharp: s.sharp ? bytes(s.sharp) : null};   // tree.tree_streams: nodes over clip lines, one bit each
  }
  // The entries to draw for a camera: the tolerance cut (a node refined while f 2 a / (|c - eye| - R) exceeds
  // the tolerance; nodes outside the frustum dropped with their subtrees), and where it holds more than the
  // budget, its refinements largest projected size first (a child's priority at most its parent's; ties:
  // shallower first), the longest prefix within the budget (Schuetz 2016, sec. 3.3). A streamed chunked
  // hierarchy (surfsplat.web.stream) is a forest: the points of the top hierarchy's leaves are the cells'
  // roots, and a loaded cell's tree continues below its root as ChunkedHierarchy.view_splats cuts it.
  var topTree = null, cells = null, cellOf = null, roots = null, cutId = 0;
  function selectCut(cam, w, h) {
    var L = H.lod, budget = Math.max(1, state.budget | 0), tol = L.tolerance;
    var f = 0.5 * h / Math.tan(cam.fov * Math.PI / 360), o = H.origin;
    var eye = sub(cam.eye, o), r = viewRows(eye, sub(cam.target, o), cam.up), nf = nearFar(cam.eye, cam.target, cam.up);
    var sx = Math.hypot(f, w / 2), sy = Math.hypot(f, h / 2);
    function sphereVisible(C, i, R) {
      var c = [C[3 * i], C[3 * i + 1], C[3 * i + 2]];
      var x = dot(r[0], c) + r[3][0], y = dot(r[1], c) + r[3][1], z = -(dot(r[2], c) + r[3][2]);
      if (z + R < nf[0] || z - R > nf[1]) return false;
      return f * Math.abs(x) - (w / 2) * z <= R * sx && f * Math.abs(y) - (h / 2) * z <= R * sy;
    }
    function sphereSize(C, i, R, a) {
      var d = Math.hypot(C[3 * i] - eye[0], C[3 * i + 1] - eye[1], C[3 * i + 2] - eye[2]) - R;
      return d < nf[0] ? Infinity : f * 2 * a / d;
    }
    function visible(t, n) { return sphereVisible(t.T.center, n, t.T.radius[n]); }
    function size(t, n) { return sphereSize(t.T.center, n, t.T.radius[n], t.T.extent[n]); }
    // a top leaf's point k: the root of a cell, continued by its tree where loaded and refined
    function cellRoot(t, n, k) {
      if (!cells || t !== topTree) return null;
      var c = cellOf[t.T.pointStart[n] + k];
      return {cell: c, size: sphereSize(roots.center, c, roots.radius[c], roots.extent[c])};
    }
    cutId += 1;
    var refined = [], base = 0, stack = [], wanted = [], n, k, t;
    for (n = topTree.offsets[0]; n < topTree.offsets[1]; ++n) if (visible(topTree, n)) { stack.push([topTree, n, Infinity, 0]); base += 1; }
    var total = base;
    while (stack.length) {
      var item = stack.pop(); t = item[0]; n = item[1];
      var own = size(t, n), S = t.T.sharp;
      // refined while larger than the tolerance, and always over clip lines (hierarchy.lod.sharp_nodes)
      if (!(own > tol) && !(S && (S[n >> 3] >> (n & 7)) & 1)) continue;
      var p = Math.min(own, item[2]), cost;
      if (t.T.childCount[n] === 0) {
        cost = t.T.pointCount[n] - 1;
        for (k = 0; cells && t === topTree && k < t.T.pointCount[n]; ++k) {
          var cr = cellRoot(t, n, k), cell = cells[cr.cell];
          if (!(cr.size > tol)) continue;
          var pc = Math.min(cr.size, p);
          var inView = sphereVisible(roots.center, cr.cell, roots.radius[cr.cell]);
          if (cell.tree) {
            if (inView) {   // in use, and what it is worth to this view, by the rule that requests it
              cell.lastUsed = cell.priorityCut = cutId;
              cell.priority = pc;
            }
            if (visible(cell.tree, 0)) stack.push([cell.tree, 0, p, item[3] + 1]);   // its root node for its root splat
            else refined.push([pc, item[3] + 1, cell.tree, -1, -1]);   // culled whole: refining its root drops it
          } else if (inView) wanted.push([pc, cr.cell]);
        }
      } else {
        cost = -1;
        for (k = 0; k < t.T.childCount[n]; ++k) {
          var child = t.T.childStart[n] + k;
          if (visible(t, child)) { cost += 1; stack.push([t, child, p, item[3] + 1]); }
        }
      }
      refined.push([p, item[3], t, n, cost]);
      total += cost;
    }
    var trees = [topTree];
    if (cells) cells.forEach(function (c) { if (c.tree) trees.push(c.tree); });
    trees.forEach(function (x) { x.open = new Uint8Array(x.M); x.dropped = false; x.out = []; });
    var stop = -Infinity;   // the priority of the first refinement the budget leaves out
    function open(x) { if (x[3] < 0) x[2].dropped = true; else x[2].open[x[3]] = 1; }
    if (total <= budget) refined.forEach(open);
    else {
      refined.sort(function (a, b) { return b[0] - a[0] || a[1] - b[1] || a[3] - b[3]; });
      var sum = base;
      for (k = 0; k < refined.length && sum + refined[k][4] <= budget; ++k) { sum += refined[k][4]; open(refined[k]); }
      if (k < refined.length) stop = refined[k][0];
    }
    var todo = [];
    for (n = topTree.offsets[0]; n < topTree.offsets[1]; ++n) if (visible(topTree, n)) todo.push([topTree, n]);
    while (todo.length) {
      var next = todo.pop(); t = next[0]; n = next[1];
      if (!t.open[n]) { t.out.push(n); continue; }
      if (t.T.childCount[n] === 0) {
        for (k = 0; k < t.T.pointCount[n]; ++k) {
          var root = cellRoot(t, n, k), sub_ = root && cells[root.cell].tree;
          if (sub_ && root.size > tol) { if (!sub_.dropped) todo.push([sub_, 0]); }
          else t.out.push(t.M + t.T.pointStart[n] + k);
        }
        continue;
      }
      for (k = 0; k < t.T.childCount[n]; ++k) if (visible(t, t.T.childStart[n] + k)) todo.push([t, t.T.childStart[n] + k]);
    }
    var drawn = 0, nodesDrawn = 0;
    trees.forEach(function (x) {
      var list = Uint32Array.from(x.out);
      for (var q = 0; q < list.length; ++q) if (list[q] < x.M) nodesDrawn += 1;
      gl.bindVertexArray(x.vao);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, list, gl.DYNAMIC_DRAW);
      gl.bindVertexArray(null);
      x.drawn = list.length;
      drawn += list.length;
      if (x.cell !== undefined && list.length) cells[x.cell].lastUsed = cutId;
      x.out = null;
    });
    state.drawn = drawn;
    state.drawnNodes = nodesDrawn;   // node splats among them (the rest: points)
    if (cells) {   // the cells worth loading: those the budget would refine, largest on screen first
      wanted = wanted.filter(function (x) { return x[0] > stop; });
      wanted.sort(function (a, b) { return b[0] - a[0] || a[1] - b[1]; });
      stream.wanted = wanted.map(function (x) { return x[1]; });
      stream.wantedPriority = wanted.map(function (x) { return x[0]; });
    }
    return drawn;
  }

  // ---- streaming the cells of a chunked hierarchy (surfsplat.web.stream) -----------------------------
  // Each cell file is a script calling surfsplatCell(index, data): scripts load from a server and from
  // file:// alike. Requests go out when the camera stops (after a full-quality frame), a few at a time;
  // loaded cells stay within the memory budget, the least recently drawn let go first.
  var stream = {requests: 0, loads: 0, evictions: 0, bytes: 0, peakBytes: 0, inflight: 0, inflightBytes: 0,
                wanted: [], wantedPriority: [], blocked: false, memoryBudget: 0, loaded: 0};
  state.stream = stream;
  function startStreaming() {
    var S = H.lod.streamed, s = DATA.streams;
    cellOf = i32(s.cell_of_point);
    roots = {center: f32(s.root_center), radius: f32(s.root_radius), extent: f32(s.root_extent)};
    cells = S.cells.map(function (c, i) { return {index: i, key: c.key, bytes: c.bytes, tree: null, loading: false, lastUsed: 0,
                                                  priority: 0, priorityCut: 0}; });
    stream.memoryBudget = Number(params.memory) >= 1 ? Math.floor(Number(params.memory)) : S.memory_budget;
    window.surfsplatCell = cellLoaded;
  }
  // The cell to let go for a request of priority p: the least recently drawn loaded cell the current cut
  // does not draw, else the drawn one of least priority in this view if below p (Potree's order: what is
  // largest on screen is kept), else null.
  function evictable(p) {
    var best = null, least = null;
    cells.forEach(function (c) {
      if (!c.tree) return;
      if (c.lastUsed < cutId) { if (!best || c.lastUsed < best.lastUsed) best = c; return; }
      var q = c.priorityCut === cutId ? c.priority : 0;
      if (q < p && (!least || q < (least.priorityCut === cutId ? least.priority : 0))) least = c;
    });
    return best || least;
  }
  function evict(c) {
    var x = c.tree;
    x.buffers.forEach(function (b) { gl.deleteBuffer(b); });
    gl.deleteVertexArray(x.vao);
    c.tree = null;
    stream.bytes -= c.bytes;
    stream.loaded -= 1;
    stream.evictions += 1;
  }
  function requestCells() {
    if (!cells) return;
    stream.blocked = false;
    var recut = false;
    for (var i = 0; i < stream.wanted.length && stream.inflight < H.lod.streamed.concurrent; ++i) {
      var c = cells[stream.wanted[i]];
      if (c.tree || c.loading) continue;
      while (stream.bytes + stream.inflightBytes + c.bytes > stream.memoryBudget) {
        var old = evictable(stream.wantedPriority[i]);
        if (!old) break;
        recut = recut || old.lastUsed === cutId;
        evict(old);
      }
      if (stream.bytes + stream.inflightBytes + c.bytes > stream.memoryBudget) { stream.blocked = true; break; }
      c.loading = true;
      stream.requests += 1;
      stream.inflight += 1;
      stream.inflightBytes += c.bytes;
      var tag = document.createElement('script');
      tag.src = H.lod.streamed.folder + '/' + encodeURIComponent(c.key) + '.js';
      tag.onload = function () { this.remove(); };
      tag.onerror = (function (cell, src) { return function () { fail('could not load ' + src); cell.loading = false; stream.inflight -= 1; stream.inflightBytes -= cell.bytes; }; })(c, tag.src);
      document.head.appendChild(tag);
    }
    stream.idle = stream.inflight === 0 && (stream.blocked || !stream.wanted.some(function (k) { return !cells[k].tree; }));
    if (recut) { clearTimeout(refineSoon); refineSoon = setTimeout(full, 0); }   // its root splat for it meanwhile
    // for the tests: the most a cell left out is worth, and the least a loaded cell drawn is worth
    stream.wantedTop = 0;
    stream.wanted.forEach(function (k, j) { if (!cells[k].tree && !cells[k].loading) stream.wantedTop = Math.max(stream.wantedTop, stream.wantedPriority[j]); });
    stream.loadedLeast = Infinity;
    cells.forEach(function (c) { if (c.tree && c.lastUsed === cutId && c.priorityCut === cutId) stream.loadedLeast = Math.min(stream.loadedLeast, c.priority); });
  }
  var refineSoon = null;
  function cellLoaded(index, data) {
    var c = cells[index];
    if (!c || !c.loading) return;
    c.loading = false;
    stream.inflight -= 1;
    stream.inflightBytes -= c.bytes;
    try {
      var d = decode(data.header, data.streams), vao = gl.createVertexArray(), buffers = [];
      gl.bindVertexArray(vao);
      buffers.push(attribute(1, d.position, 3, gl.FLOAT, false), attribute(2, d.normal, 3, gl.FLOAT, false),
                   attribute(3, d.color, 3, gl.UNSIGNED_BYTE, true), attribute(4, d.u, 3, gl.FLOAT, false),
                   attribute(5, d.v, 3, gl.FLOAT, false));
      var el = gl.createBuffer();
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, el);
      buffers.push(el);
      gl.bindVertexArray(null);
      c.tree = {T: readTree(data.streams), M: data.header.lod.nodes, offsets: data.header.lod.level_offsets, vao: vao,
                elements: el, buffers: buffers, drawn: 0, cell: index};
      if (H.color.modes.length) {   // what recolouring it needs (not the rest of its streams)
        var attrs = {};
        for (var key in data.streams) if (key.indexOf('attr_') === 0) attrs[key] = data.streams[key];
        c.tree.data = {header: data.header, streams: attrs};
        c.tree.position = d.position;
        c.tree.color = d.color;
      }
      if (state.colorBy !== OWN_COLORS) recolorCell(c);
    } catch (e) { fail(String(e && e.message || e)); return; }
    c.lastUsed = cutId;
    stream.loads += 1;
    stream.loaded += 1;
    stream.bytes += c.bytes;
    stream.peakBytes = Math.max(stream.peakBytes, stream.bytes);
    stream.idle = false;
    clearTimeout(refineSoon);   // a full frame with it once the camera is still (and more requests)
    refineSoon = setTimeout(function () { if (performance.now() - lastChange >= SETTLE_MS) full(); else request(); }, 30);
  }

  // ---- targets ------------------------------------------------------------------------------------
  var targets = null;
  function texture(format, w, h) {
    var t = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, t);
    var internal = {r: gl.R32F, rg: gl.RG32F, rgba: gl.RGBA32F, depth: gl.DEPTH_COMPONENT24}[format];   // the desktop's depth
    gl.texStorage2D(gl.TEXTURE_2D, 1, internal, w, h);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    return t;
  }
  function framebuffer(colors, depth) {
    var f = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, f);
    colors.forEach(function (t, i) { gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0 + i, gl.TEXTURE_2D, t, 0); });
    if (depth) gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.TEXTURE_2D, depth, 0);
    gl.drawBuffers(colors.map(function (t, i) { return gl.COLOR_ATTACHMENT0 + i; }));
    if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) throw new Error('incomplete framebuffer');
    return f;
  }
  function ensureTargets(w, h) {
    if (targets && targets.w === w && targets.h === h) return targets;
    if (targets) targets.all.forEach(function (x) { gl.isTexture(x) ? gl.deleteTexture(x) : gl.deleteFramebuffer(x); });
    var t = {w: w, h: h, side: texture('rg', w, h), cracks: texture('rg', w, h), accum: texture('rgba', w, h),
             aux: texture('rgba', w, h), depth: texture('depth', w, h), out: texture('rgba', w, h),
             depthSum: texture('rg', w, h), cover: texture('rgba', w, h),
             normColor: texture('rgba', w, h), normDepth: texture('rg', w, h), normZ: texture('r', w, h)};
    t.fboVisibility = framebuffer([t.side]);
    t.fboCracks = framebuffer([t.cracks]);
    t.fboAccum = framebuffer([t.accum, t.aux], t.depth);
    t.fboAccumCover = framebuffer([t.accum, t.aux, t.cover], t.depth);   // ewa: with edge coverage
    t.fboOut = framebuffer([t.out, t.depthSum]);
    t.fboNorm = framebuffer([t.normColor, t.normDepth, t.normZ]);   // normalize.frag's, for the fill pass
    t.all = [t.fboVisibility, t.fboCracks, t.fboAccum, t.fboAccumCover, t.fboOut, t.fboNorm, t.side, t.cracks, t.accum,
             t.aux, t.depth, t.out, t.depthSum, t.cover, t.normColor, t.normDepth, t.normZ];
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    targets = t;
    return t;
  }
  function bindTexture(unit, t) { gl.activeTexture(gl.TEXTURE0 + unit); gl.bindTexture(gl.TEXTURE_2D, t); }

  // ---- a frame: the passes of surfsplat.rendering.passes ------------------------------------------
  // Whether the eye lies outside the model's bounds: the view plan's back-face culling (H.culls, View.culls
  // for the exported view) holds only there (geometry/closed.eye_outside); inside, the page draws two-sided.
  function eyeOutside(eye) {
    var lo = H.bounds[0], hi = H.bounds[1];
    for (var i = 0; i < 3; i++) if (eye[i] < lo[i] || eye[i] > hi[i]) return true;
    return false;
  }
  function frameValues(cam, w, h, technique) {
    var o = H.origin, eye = sub(cam.eye, o), target = sub(cam.target, o);
    var r = viewRows(eye, target, cam.up), nf = nearFar(cam.eye, cam.target, cam.up);
    var view = [r[0][0], r[1][0], r[2][0], 0, r[0][1], r[1][1], r[2][1], 0, r[0][2], r[1][2], r[2][2], 0,
                r[3][0], r[3][1], r[3][2], 1];   // column-major
    // the headlight (Lights() default): from the target toward the eye, in camera space
    var l = unit(sub(cam.eye, cam.target)), light = [dot(r[0], l), dot(r[1], l), dot(r[2], l)];
    var fr = H.frame;
    return {
      u_view: view, u_tile: [0, 0, w, h], u_viewport: [w, h], u_near_far: nf,
      u_focal: 0.5 * h / Math.tan(cam.fov * Math.PI / 360),
      u_light_dirs: [light, [0, 0, 0], [0, 0, 0], [0, 0, 0]], u_material: H.material, u_num_lights: 1,
      u_lighting: true, u_depth_epsilon: fr.u_depth_epsilon, u_supersample: state.supersample,
      u_cull_backfaces: !!(H.culls && H.culls[technique]) && eyeOutside(cam.eye), u_separate_sides: fr.u_separate_sides,
      u_clip_fringe: fr.u_clip_fringe, u_deferred: fr.u_deferred
    };
  }

  function drawSplats(name, values, frame, technique) {
    if (preview) {   // the decimated first preview (technique points)
      setUniforms(program('points_points'), Object.assign({u_max_point: maxPoint}, values));
      gl.bindVertexArray(preview.vao);
      gl.drawArrays(gl.POINTS, 0, preview.count);
      gl.bindVertexArray(null);
      return;
    }
    if (H.lod) {   // every entry of the cut as a point (node splats stay within the tolerance or the budget's)
      setUniforms(program(name + '_points'), Object.assign({u_max_point: maxPoint}, values));
      var trees = [topTree];
      if (cells) cells.forEach(function (c) { if (c.tree) trees.push(c.tree); });
      trees.forEach(function (x) {
        if (!x.drawn) return;
        gl.bindVertexArray(x.vao);
        gl.drawElements(gl.POINTS, x.drawn, gl.UNSIGNED_INT, 0);
      });
      gl.bindVertexArray(null);
      return;
    }
    var quads = Math.min(largerThan(pointRadius(frame, technique)), quadCount);
    if (quads > 0) {
      setUniforms(program(name), values);
      gl.bindVertexArray(quadsVao);
      gl.drawArrays(gl.TRIANGLES, 0, 6 * quads);
    }
    if (quads < H.count) {
      setUniforms(program(name + '_points'), Object.assign({u_max_point: maxPoint}, values));
      gl.bindVertexArray(pointsVao);
      gl.drawArrays(gl.POINTS, quads, H.count - quads);
    }
    gl.bindVertexArray(null);
    state.quads = quads;
  }
  function fullscreen(p, values) {
    setUniforms(p, values);
    gl.bindVertexArray(empty);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    gl.bindVertexArray(null);
  }

  var probe = new Uint8Array(4), probeFloat = new Float32Array(4);
  // ?profile=1: wait after each pass and keep its time (state.passMs), for the benchmark
  function mark(name) {
    if (!state.profile) return;
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.FLOAT, probeFloat);   // every pass draws into a float target
    var now = performance.now();
    state.passMs[name] = now - state.passStart;
    state.passStart = now;
  }
  // A supersampled page (?supersample=K, export's supersample) draws every pass on K x K sub-pixels a pixel, as
  // `surfsplat render --supersample K` does, then reduces them (downsample.frag) into the canvas.
  var reduced = null;
  function ensureReduced(w, h) {
    if (reduced && reduced.w === w && reduced.h === h) return reduced;
    if (reduced) reduced.all.forEach(function (x) { gl.isTexture(x) ? gl.deleteTexture(x) : gl.deleteFramebuffer(x); });
    var r = {w: w, h: h, out: texture('rgba', w, h), depthSum: texture('rg', w, h)};
    r.fbo = framebuffer([r.out, r.depthSum]);
    r.all = [r.fbo, r.out, r.depthSum];
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    reduced = r;
    return r;
  }
  function render(technique) {
    technique = technique || state.technique;
    var K = state.supersample, sub = K > 1;
    var w = canvas.width * K, h = canvas.height * K, t = ensureTargets(w, h);
    var start = performance.now();
    state.passMs = {}; state.passStart = start;
    var frame = frameValues(state.camera, w, h, technique);
    writeBlocks(frame);
    var own = Object.assign({u_side: SIDE_UNIT}, H.uniforms[technique] || {});
    gl.viewport(0, 0, w, h);
    gl.disable(gl.CULL_FACE);
    gl.bindFramebuffer(gl.FRAMEBUFFER, t.fboAccum);
    gl.depthMask(true);
    gl.clearBufferfv(gl.COLOR, 0, [0, 0, 0, 0]);
    gl.clearBufferfv(gl.COLOR, 1, [0, 0, 0, 0]);
    gl.clearBufferfv(gl.DEPTH, 0, [1]);
    // blended with edge coverage (shaders.py: <technique>_accumulation, normalize_edges)
    var blended = H.blended.indexOf(technique) >= 0;
    if (blended) {
      gl.bindFramebuffer(gl.FRAMEBUFFER, t.fboAccumCover);
      gl.clearBufferfv(gl.COLOR, 2, [0, 0, 0, 0]);
    }
    if (blended) {
      // 1. visibility: per pixel the nearest offset depths by MIN blending
      gl.bindFramebuffer(gl.FRAMEBUFFER, t.fboVisibility);
      gl.clearBufferfv(gl.COLOR, 0, [NO_DEPTH, NO_DEPTH, 0, 0]);
      gl.disable(gl.DEPTH_TEST);
      gl.enable(gl.BLEND);
      gl.blendEquation(gl.MIN);
      drawSplats(technique + '_visibility', own, frame, technique);
      mark('visibility');
      // 2. cracks: the record with one-pixel cracks marked
      gl.disable(gl.BLEND);
      gl.bindFramebuffer(gl.FRAMEBUFFER, t.fboCracks);
      bindTexture(SIDE_UNIT, t.side);
      fullscreen(program('cracks'), {u_side: SIDE_UNIT});
      mark('cracks');
      // 3. accumulation: additive blending of the weighted colours, depths and normals
      bindTexture(SIDE_UNIT, t.cracks);
      gl.bindFramebuffer(gl.FRAMEBUFFER, t.fboAccumCover);
      gl.depthMask(false);
      gl.enable(gl.BLEND);
      gl.blendEquation(gl.FUNC_ADD);
      gl.blendFunc(gl.ONE, gl.ONE);
      drawSplats(technique + '_accumulation', own, frame, technique);
      mark('accumulation');
    } else {
      // the one opaque pass: a plain z-buffer
      gl.enable(gl.DEPTH_TEST);
      gl.depthFunc(gl.LESS);
      gl.disable(gl.BLEND);
      drawSplats(technique, own, frame, technique);
      mark('opaque');
      bindTexture(SIDE_UNIT, t.side);
    }
    // normalization (and eye-dome lighting from its depth)
    gl.depthMask(true);
    gl.disable(gl.BLEND);
    gl.disable(gl.DEPTH_TEST);
    bindTexture(0, t.accum);
    bindTexture(1, t.aux);
    if (blended) bindTexture(COVER_UNIT, t.cover);
    var normalization = program(blended ? 'normalize_edges' : 'normalize');
    var normalize = {u_accum: 0, u_aux: 1, u_side: SIDE_UNIT, u_cover: COVER_UNIT, u_background: state.background,
                     u_edge_fringe: blended && H.edge_fringe.indexOf(technique) >= 0};
    // the last pass writes the canvas, or the targets eye-dome lighting reads
    var last = function () { gl.bindFramebuffer(gl.FRAMEBUFFER, state.edl || sub ? t.fboOut : null); };
    if (H.fill) {   // normalization into the norm targets, then the fill pass (passes.FillPass, fill.frag)
      gl.bindFramebuffer(gl.FRAMEBUFFER, t.fboNorm);
      fullscreen(normalization, normalize);
      mark('normalization');
      last();
      bindTexture(NORM_COLOR_UNIT, t.normColor);
      bindTexture(NORM_DEPTH_UNIT, t.normDepth);
      bindTexture(NORM_Z_UNIT, t.normZ);
      var fill = H.fill[String(K)];
      fullscreen(program(fill.program), {u_norm_color: NORM_COLOR_UNIT, u_norm_depth: NORM_DEPTH_UNIT,
                                          u_norm_z: NORM_Z_UNIT, u_fill_depth: fill.depth});
    } else {
      last();
      fullscreen(normalization, normalize);
    }
    var image = t;   // what eye-dome lighting reads: the normalized (filled) image, reduced where supersampled
    if (sub) {
      gl.viewport(0, 0, canvas.width, canvas.height);
      if (state.edl) { image = ensureReduced(canvas.width, canvas.height); gl.bindFramebuffer(gl.FRAMEBUFFER, image.fbo); }
      else gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      bindTexture(EDL_COLOR_UNIT, t.out);
      bindTexture(EDL_DEPTH_UNIT, t.depthSum);
      fullscreen(program('downsample'), {u_sub_color: EDL_COLOR_UNIT, u_sub_depth: EDL_DEPTH_UNIT, u_factor: K});
    }
    if (state.edl) {
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      bindTexture(EDL_COLOR_UNIT, image.out);
      bindTexture(EDL_DEPTH_UNIT, image.depthSum);
      fullscreen(program('edl'), {u_color: EDL_COLOR_UNIT, u_depth: EDL_DEPTH_UNIT, u_background: state.background,
                                u_edl_strength: H.edl.strength, u_edl_offsets: [].concat.apply([], H.edl.offsets)});
    }
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, probe);   // waits for the frame (gl.finish need not)
    state.frameMs = performance.now() - start;
    state.frames += 1;
    var error = gl.getError();
    if (error !== gl.NO_ERROR) fail('WebGL error ' + error + ' while drawing');
  }

  // ---- camera, URL, interaction ---------------------------------------------------------------------
  function parseVec(text) {
    var v = String(text).split(',').map(Number);
    return v.length === 3 && v.every(isFinite) ? v : null;
  }

  function sizeCanvas() {
    var dpr = window.devicePixelRatio || 1;
    var w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; return true; }
    return false;
  }

  function fmt(v) { return v.map(function (x) { return Number(x.toPrecision(10)); }).join(','); }
  var urlTimer = null;
  function saveUrl() {
    clearTimeout(urlTimer);
    urlTimer = setTimeout(function () {
      var c = state.camera;
      var hash = '#eye=' + fmt(c.eye) + '&target=' + fmt(c.target) + '&up=' + fmt(c.up) + '&fov=' + c.fov +
                 '&technique=' + state.technique + (state.colorBy !== OWN_COLORS ? '&color=' + encodeURIComponent(state.colorBy) : '') + (state.edl !== (state.technique === 'points') ? '&edl=' + (state.edl ? 1 : 0) : '') +
                 (state.supersample !== (H.supersample || 1) ? '&supersample=' + state.supersample : '');
      if (options.url) {
        try { history.replaceState(null, '', location.pathname + location.search + hash); } catch (e) { /* file:// in some browsers */ }
      }
      if (options.onCamera) options.onCamera({eye: c.eye.slice(), target: c.target.slice(), up: c.up.slice(), fov: c.fov});
    }, 250);
  }

  var homeCamera = null;
  function home() {
    state.camera = defaultCamera(canvas.width, canvas.height);
    homeCamera = state.camera;
  }

  var dirty = true;
  function request() {
    if (!dirty) { dirty = true; requestAnimationFrame(tick); }
  }
  function changed() { state.moved = true; lastChange = performance.now(); saveUrl(); request(); }

  function orbit(dx, dy) {   // radians about the world up through the target, then about the screen right
    var c = state.camera, up = unit(c.up), offset = sub(c.eye, c.target);
    offset = rotate(offset, up, -dx);
    var right = unit(cross(sub(c.target, c.eye), up));
    var turned = rotate(offset, right, -dy);
    if (Math.abs(dot(unit(turned), up)) < 0.999) offset = turned;   // never over the pole
    c.eye = add(c.target, offset);
  }
  function pan(dx, dy) {   // pixels
    var c = state.camera, dist = norm(sub(c.eye, c.target));
    var per = 2 * dist * Math.tan(c.fov * Math.PI / 360) / canvas.clientHeight;
    var f = unit(sub(c.target, c.eye)), right = unit(cross(f, c.up)), up = cross(right, f);
    var move = add(scale(right, -dx * per), scale(up, dy * per));
    c.eye = add(c.eye, move);
    c.target = add(c.target, move);
  }
  function zoom(factor) {
    var c = state.camera;
    c.eye = add(c.target, scale(sub(c.eye, c.target), factor));
  }

  var drag = null, pointers = {};
  canvas.addEventListener('pointerdown', function (e) {
    canvas.focus();
    canvas.setPointerCapture(e.pointerId);
    pointers[e.pointerId] = [e.clientX, e.clientY];
    drag = {x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button === 2 || e.button === 1};
  });
  canvas.addEventListener('pointermove', function (e) {
    if (!(e.pointerId in pointers)) return;
    var ids = Object.keys(pointers);
    if (ids.length === 2) {   // pinch: zoom by the change of the fingers' distance, pan by their midpoint
      var other = pointers[ids[0] == e.pointerId ? ids[1] : ids[0]], before = pointers[e.pointerId];
      var d0 = Math.hypot(before[0] - other[0], before[1] - other[1]), d1 = Math.hypot(e.clientX - other[0], e.clientY - other[1]);
      if (d0 > 0 && d1 > 0) zoom(d0 / d1);
      pan((e.clientX - before[0]) / 2, (e.clientY - before[1]) / 2);
    } else if (drag) {
      var dx = e.clientX - drag.x, dy = e.clientY - drag.y;
      if (drag.pan) pan(dx, dy); else orbit(dx * 0.01, dy * 0.01);
      drag.x = e.clientX; drag.y = e.clientY;
    }
    pointers[e.pointerId] = [e.clientX, e.clientY];
    changed();
  });
  function release(e) { delete pointers[e.pointerId]; if (!Object.keys(pointers).length) drag = null; }
  canvas.addEventListener('pointerup', release);
  canvas.addEventListener('pointercancel', release);
  canvas.addEventListener('contextmenu', function (e) { e.preventDefault(); });
  canvas.addEventListener('wheel', function (e) {
    e.preventDefault();
    zoom(Math.exp(e.deltaY * (e.deltaMode === 1 ? 0.05 : 0.0015)));
    changed();
  }, {passive: false});
  canvas.addEventListener('keydown', function (e) {
    var step = 0.1, px = 40, handled = true;
    if (e.key === 'ArrowLeft') { if (e.shiftKey) pan(px, 0); else orbit(-step, 0); }
    else if (e.key === 'ArrowRight') { if (e.shiftKey) pan(-px, 0); else orbit(step, 0); }
    else if (e.key === 'ArrowUp') { if (e.shiftKey) pan(0, px); else orbit(0, -step); }
    else if (e.key === 'ArrowDown') { if (e.shiftKey) pan(0, -px); else orbit(0, step); }
    else if (e.key === '+' || e.key === '=') zoom(0.9);
    else if (e.key === '-' || e.key === '_') zoom(1 / 0.9);
    else handled = false;
    if (handled) { e.preventDefault(); changed(); }
  });
  root.addEventListener('keydown', function (e) {
    if (e.target && (e.target.tagName === 'INPUT' || e.target.tagName === 'SELECT')) return;
    if (e.key === 'Home' || e.key === '0') { home(); changed(); }
    else if (e.key === 't' || e.key === 'T') { var ts = H.techniques; setTechnique(ts[(ts.indexOf(state.technique) + 1) % ts.length]); }
    else if (e.key === 'e' || e.key === 'E') { state.edl = !state.edl; syncControls(); changed(); }
    else if (e.key === 'p' || e.key === 'P') screenshot();
    else if (e.key === 'c' || e.key === 'C') { var cs = colorModes(); setColorBy(cs[(cs.indexOf(state.colorBy) + 1) % cs.length]); }
  });

  function setTechnique(name) {
    if (!(name in H.uniforms)) return;
    if (H.blended.indexOf(name) >= 0 && !floatBlend) { fail(name + ' needs EXT_float_blend, which this browser lacks'); return; }
    state.technique = name;
    syncControls();
    changed();
  }

  function screenshot() {
    render(preview ? 'points' : state.technique);
    var link = document.createElement('a');
    link.download = String(H.name).split(/[\\/]/).pop().replace(/\.[^.]*$/, '') + '-' + state.technique + '.png';
    link.href = canvas.toDataURL('image/png');
    link.click();
  }

  // ---- controls -------------------------------------------------------------------------------------
  var select = $('technique'), bg = $('background'), edlBox = $('edl'), hud = $('hud');
  if (H.lod) {
    $('panel').insertAdjacentHTML('beforeend', '<label>Point budget <input id="budget" type="number" min="1" ' +
                                  'step="100000" aria-label="point budget" style="width: 8em"></label>');
    $('budget').addEventListener('change', function () {
      var v = Math.floor(Number($('budget').value));
      if (v >= 1) { state.budget = v; state.lastChange = 0; changed(); }
    });
  }
  H.techniques.forEach(function (t) { var o = document.createElement('option'); o.value = o.textContent = t; select.appendChild(o); });
  var colorSelect = $('color');
  colorModes().forEach(function (t) { var o = document.createElement('option'); o.value = o.textContent = t; colorSelect.appendChild(o); });
  colorSelect.addEventListener('change', function () { setColorBy(colorSelect.value); });
  function hex(c) { return '#' + c.map(function (x) { return ('0' + Math.round(Math.min(1, Math.max(0, x)) * 255).toString(16)).slice(-2); }).join(''); }
  function syncControls() {
    select.value = state.technique; bg.value = hex(state.background); edlBox.checked = state.edl;
    colorSelect.value = state.colorBy;
    if (H.lod) $('budget').value = state.budget;
  }
  select.addEventListener('change', function () { setTechnique(select.value); });
  bg.addEventListener('input', function () {
    var v = bg.value; state.background = [1, 3, 5].map(function (i) { return parseInt(v.substr(i, 2), 16) / 255; });
    root.style.background = v;
    request();
  });
  edlBox.addEventListener('change', function () { state.edl = edlBox.checked; changed(); });
  $('home').addEventListener('click', function () { home(); changed(); });
  $('screenshot').addEventListener('click', screenshot);
  var helpButton = $('helpbutton'), help = $('help');
  helpButton.addEventListener('click', function () {
    var open = help.style.display !== 'block';
    help.style.display = open ? 'block' : 'none';
    helpButton.setAttribute('aria-expanded', String(open));
  });
  // Below COMPACT_WIDTH CSS pixels (a phone, a small notebook cell) the controls fold behind one button,
  // so that they cover a corner of the picture rather than a third of it.
  var COMPACT_WIDTH = 640, panel = $('panel'), menu = $('menu');
  function fitControls() {
    var compact = root.clientWidth < COMPACT_WIDTH;
    if (compact !== root.classList.contains('compact')) {
      root.classList.toggle('compact', compact);
      panel.classList.remove('open');
      menu.setAttribute('aria-expanded', 'false');
    }
    state.compact = compact;
  }
  menu.addEventListener('click', function () {
    var open = panel.classList.toggle('open');
    menu.setAttribute('aria-expanded', String(open));
  });
  fitControls();
  window.addEventListener('resize', function () { fitControls(); if (sizeCanvas()) request(); });
  if (window.ResizeObserver) new ResizeObserver(function () { fitControls(); if (sizeCanvas()) request(); }).observe(canvas);

  // Where a full-quality frame is slow (CPU WebGL: SwiftShader), a moving camera and the first frame are
  // drawn with "points" (one pass, the cheapest), and the full frame follows when the camera stops.
  var PREVIEW_MS = 250, SETTLE_MS = 300;
  var lastFullMs = null, lastChange = 0, refineTimer = null;
  function hudText(technique, ms, moving) {
    hud.textContent = (preview ? preview.count : H.lod ? state.drawn : H.count).toLocaleString('en') + ' splats drawn \u00b7 ' + ms.toFixed(1) + ' ms/frame \u00b7 ' +
                      technique + (state.edl ? ' + EDL' : '') +
                      (cells ? ' \u00b7 ' + stream.loaded + '/' + cells.length + ' cells loaded' : '') +
                      (preview ? ' (preview: 1 splat in ' + preview.step + '; loading the others)' : moving ? ' (preview; full quality when still)' : '');
  }
  function full() {
    refineTimer = null;
    try { if (H.lod) selectCut(state.camera, canvas.width, canvas.height); render(); } catch (e) { fail(String(e && e.message || e)); return; }
    state.fullFrames = (state.fullFrames || 0) + 1;
    if (cells) {   // requests once the camera is still
      var wait = SETTLE_MS - (performance.now() - lastChange);
      clearTimeout(refineSoon);
      if (wait <= 0) requestCells(); else refineSoon = setTimeout(full, wait);
    }
    lastFullMs = state.frameMs;
    hudText(state.technique, state.frameMs, false);
    if (!state.ready) {
      state.ready = true;
      state.readyMs = performance.now();
      root.setAttribute('data-ready', '1');
    }
  }
  // after the decimated preview (drawn, and shown before this long task): every splat, then full quality
  function loadAll() {
    refineTimer = null;
    if (!preview) return;
    try { loadSplats(); } catch (e) { fail(String(e && e.message || e)); return; }
    full();
  }
  function tick() {
    dirty = false;
    if (sizeCanvas() && !params.eye && !state.moved) home();
    var slow = lastFullMs === null || lastFullMs > PREVIEW_MS;
    clearTimeout(refineTimer);
    if (preview) {
      try { render('points'); } catch (e) { fail(String(e && e.message || e)); return; }
      if (state.firstFrameMs === null) {
        state.timings.preview = state.frameMs;
        if (state.profile) state.timings.previewPasses = Object.assign({}, state.passMs);
      }
      hudText('points', state.frameMs, true);
      refineTimer = setTimeout(function () { requestAnimationFrame(function () { setTimeout(loadAll, 0); }); }, 0);
    } else if (state.technique !== 'points' && slow) {
      try { render('points'); } catch (e) { fail(String(e && e.message || e)); return; }
      hudText('points', state.frameMs, true);
      var wait = Math.max(0, SETTLE_MS - (performance.now() - lastChange));
      refineTimer = setTimeout(function () { requestAnimationFrame(function () { setTimeout(full, 0); }); },
                               state.ready ? wait : 0);
    } else {
      full();
    }
    if (state.firstFrameMs === null) {
      state.firstFrameMs = performance.now();
      state.firstDrawn = preview ? preview.count : H.lod ? state.drawn : H.count;   // splats the first frame drew
      root.setAttribute('data-first-frame', '1');
      if (state.profile) state.firstImage = canvas.toDataURL('image/png');   // the benchmark's look at it
    }
  }

  // ---- start ----------------------------------------------------------------------------------------
  try {
    state.profile = params.profile === '1';
    state.timings.start = performance.now();   // ms after navigation: the page's scripts loaded and parsed
    if (params.ui === '0') { state.ui = false; root.classList.add('noui'); }
    if (params.technique && params.technique in H.uniforms) state.technique = params.technique;
    var K = Math.floor(Number(params.supersample || H.supersample || 1));
    state.supersample = K >= 1 && K <= H.max_supersample ? K : 1;
    if (params.background) { var b = parseVec(params.background); if (b) state.background = b; }
    state.edl = params.edl !== undefined ? params.edl === '1' : state.technique === 'points';
    if (H.blended.indexOf(state.technique) >= 0 && !floatBlend) state.technique = 'flat';
    root.style.background = hex(state.background);
    var step = previewStep();
    state.previewStep = step;
    if (step > 1) {   // the first frame from every step-th splat (the rest decoded after it: loadAll)
      var t1 = performance.now();
      pageCodes = {};
      preview = uploadPreview(decode(H, DATA.streams, step, Math.sqrt(step), pageCodes), step);
      state.timings.previewLoad = performance.now() - t1;
    } else loadSplats();
    sizeCanvas();
    home();
    var eye = parseVec(params.eye || ''), target = parseVec(params.target || ''), up = parseVec(params.up || '');
    if (eye) {
      state.camera = {eye: eye, target: target || homeCamera.target, up: up || homeCamera.up,
                      fov: Number(params.fov) > 0 ? Number(params.fov) : H.fov};
      state.moved = true;
    }
    if (H.lod) {   // a browser-LOD page's first frame: the cut within the preview's budget (coarser nodes)
      var budget = state.budget;
      state.budget = Math.min(budget, previewSplats());
      selectCut(state.camera, canvas.width, canvas.height);
      state.budget = budget;
    }
    syncControls();
    if (params.color && params.color !== OWN_COLORS) setColorBy(params.color);
    dirty = false;
    request();
  } catch (e) {
    fail(String(e && e.message || e));
  }
  return state;
}

// The viewer's style and elements (ids are looked up inside its root element only).
var SURFSPLAT_CSS = ".surfsplat-root { position: relative; overflow: hidden; font: 13px/1.4 system-ui, sans-serif; }\n.surfsplat-root #view { display: block; width: 100%; height: 100%; touch-action: none; outline: none; }\n.surfsplat-root #view:focus-visible { outline: 2px solid #3b82f6; outline-offset: -2px; }\n.surfsplat-root .overlay { position: absolute; background: rgba(255, 255, 255, 0.85); color: #111; border-radius: 6px;\n  padding: 6px 8px; box-shadow: 0 1px 4px rgba(0, 0, 0, 0.25); }\n.surfsplat-root #panel { top: 8px; left: 8px; display: flex; gap: 8px; align-items: center; flex-wrap: wrap; max-width: 95%; }\n.surfsplat-root #panel label { display: inline-flex; gap: 4px; align-items: center; }\n.surfsplat-root #hud { bottom: 8px; left: 8px; font-variant-numeric: tabular-nums; }\n.surfsplat-root #help { bottom: 8px; right: 8px; max-width: 22em; display: none; }\n.surfsplat-root #message { top: 50%; left: 50%; transform: translate(-50%, -50%); display: none; max-width: 40em; white-space: pre-wrap; }\n.surfsplat-root.noui .overlay { display: none !important; }\n.surfsplat-root #menu { display: none; }\n.surfsplat-root.compact #menu { display: inline-block; }\n.surfsplat-root.compact #panel { top: 4px; left: 4px; padding: 3px 5px; gap: 4px; font-size: 12px; max-width: calc(100% - 8px); }\n.surfsplat-root.compact #panel:not(.open) > :not(#menu) { display: none; }\n.surfsplat-root.compact #panel.open { flex-direction: column; align-items: flex-start; max-height: calc(100% - 8px); overflow: auto; }\n.surfsplat-root.compact #hud { bottom: 4px; left: 4px; padding: 2px 5px; font-size: 11px; max-width: calc(100% - 8px); }\n.surfsplat-root.compact #help { right: 4px; bottom: 4px; font-size: 12px; }\n.surfsplat-root button, .surfsplat-root select, .surfsplat-root input { font: inherit; }";
var SURFSPLAT_MARKUP = "<canvas id=\"view\" tabindex=\"0\" role=\"img\" aria-label=\"3D view: drag or arrow keys to orbit, shift to pan, wheel or +/- to zoom\"></canvas>\n<div id=\"panel\" class=\"overlay\" role=\"toolbar\" aria-label=\"viewer controls\">\n  <button id=\"menu\" type=\"button\" aria-expanded=\"false\" aria-controls=\"panel\" title=\"show the controls\">\u2630 Controls</button>\n  <label>Technique <select id=\"technique\" aria-label=\"technique\"></select></label>\n  <label>Colour <select id=\"color\" aria-label=\"colour by\"></select></label>\n  <label>Background <input id=\"background\" type=\"color\" aria-label=\"background colour\"></label>\n  <label><input id=\"edl\" type=\"checkbox\"> Eye-dome lighting</label>\n  <button id=\"home\" type=\"button\" title=\"back to the default view (Home)\">Reset view</button>\n  <button id=\"screenshot\" type=\"button\" title=\"save the picture as PNG (P)\">Screenshot</button>\n  <button id=\"helpbutton\" type=\"button\" aria-expanded=\"false\" aria-controls=\"help\">Keys</button>\n</div>\n<div id=\"hud\" class=\"overlay\" aria-live=\"off\"></div>\n<div id=\"help\" class=\"overlay\">\n  Drag: orbit. Shift+drag or right drag: pan. Wheel or pinch: zoom.<br>\n  Arrows: orbit; Shift+arrows: pan; + / -: zoom; Home or 0: default view;\n  T: next technique; C: colour by (own colours, elevation, each attribute); E: eye-dome lighting; P: screenshot. The address holds the camera: copy it to share the view.\n</div>\n<div id=\"message\" class=\"overlay\" role=\"alert\"></div>";

// The query and hash of the page's address as a dictionary (the camera, technique, ui, ...).
function surfsplatParams() {
  var out = {}, parts = (location.search.slice(1) + '&' + location.hash.slice(1)).split('&');
  parts.forEach(function (kv) {
    if (!kv) return;
    var i = kv.indexOf('='), k = decodeURIComponent(i < 0 ? kv : kv.slice(0, i));
    out[k] = i < 0 ? '' : decodeURIComponent(kv.slice(i + 1));
  });
  return out;
}

// The exported page: its scripts set the programs and the data; the viewer fills the body.
if (typeof window !== 'undefined' && window.SURFSPLAT_DATA && window.SURFSPLAT_SHADERS && !window.surfsplat) {
  window.surfsplat = surfsplatViewer(document.body, window.SURFSPLAT_SHADERS, window.SURFSPLAT_DATA,
                                     {params: surfsplatParams(), url: true});
}
