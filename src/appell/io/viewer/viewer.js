/* appell's motion viewer: plays the frames of appell.io.viewer.scene.scene_data with
 * three.js (the global THREE of three.min.js). One viewer per <div class="appell-viewer">
 * whose data sits in the <script type="application/json"> named by its data-scene
 * attribute. Works offline; no network, no modules.
 *
 * Time is shared with the page: the viewer sends "appell-time" events (detail: {t}) on the
 * document as it plays, and follows "appell-seek" events (detail: {t}) sent by the plots.
 * The page's address may hold "#t=1.5" (show that time, paused) or "#bench=300" (render
 * 300 frames as fast as possible and write the rate into data-viewer-fps).
 */
(function () {
  "use strict";
  var PALETTE = [0x4e79a7, 0xf28e2b, 0x59a14f, 0xb07aa1, 0x76b7b2, 0xedc948, 0xff9da7, 0x9c755f, 0xbab0ac, 0xe15759];
  var KIND_COLOUR = { force: 0xd62728, moment: 0x1f77b4 };

  function vec(a, i) { return new THREE.Vector3(a[3 * i], a[3 * i + 1], a[3 * i + 2]); }

  function frameAt(times, t) {  // the last frame at or before t
    var lo = 0, hi = times.length - 1;
    if (t <= times[0]) return 0;
    if (t >= times[hi]) return hi;
    while (hi - lo > 1) { var mid = (lo + hi) >> 1; if (times[mid] <= t) lo = mid; else hi = mid; }
    return lo;
  }

  function basis(up) {  // two unit vectors normal to up
    var u = new THREE.Vector3().fromArray(up).normalize();
    var a = Math.abs(u.x) < 0.9 ? new THREE.Vector3(1, 0, 0) : new THREE.Vector3(0, 1, 0);
    a.sub(u.clone().multiplyScalar(a.dot(u))).normalize();
    return [a, new THREE.Vector3().crossVectors(u, a), u];
  }

  function bar(a, b, radius, material) {  // a cylinder from a to b (THREE.Vector3)
    var d = new THREE.Vector3().subVectors(b, a), len = d.length();
    var mesh = new THREE.Mesh(new THREE.CylinderGeometry(radius, radius, Math.max(len, 1e-9), 12), material);
    mesh.position.copy(a).add(b).multiplyScalar(0.5);
    if (len > 0) mesh.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), d.normalize());
    return mesh;
  }

  // an arrow along +y from the origin: a shaft and one head (two for a moment), drawn over
  // the bodies (no depth test) so that a force at a pin is never hidden inside it
  function arrow(colour, radius, double) {
    var m = new THREE.MeshBasicMaterial({ color: colour, depthTest: false, transparent: true, opacity: 0.9 });
    var group = new THREE.Group();
    var shaft = new THREE.Mesh(new THREE.CylinderGeometry(radius, radius, 1, 8), m);
    var heads = [new THREE.Mesh(new THREE.ConeGeometry(1, 1, 16), m)];
    if (double) heads.push(new THREE.Mesh(new THREE.ConeGeometry(1, 1, 16), m));
    group.add(shaft); heads.forEach(function (h) { group.add(h); });
    group.renderOrder = 10; shaft.renderOrder = 10; heads.forEach(function (h) { h.renderOrder = 10; });
    group.userData.setLength = function (len, head) {
      var body = Math.max(len - head * heads.length * 0.8, 1e-9);
      shaft.scale.set(1, body, 1); shaft.position.set(0, body / 2, 0);
      heads.forEach(function (h, i) {
        h.scale.set(0.38 * head, head, 0.38 * head);
        h.position.set(0, len - head / 2 - i * 0.8 * head, 0);
      });
    };
    return group;
  }

  // a grid of cells x cells squares of side step in the local x-z plane (as THREE.GridHelper),
  // each line cut into cell-long pieces: a software renderer drops a whole segment that
  // passes behind the camera, which a followed mechanism's grid does
  function gridLines(cells, step) {
    var half = cells * step / 2, xyz = [], colours = [], minor = [0.85, 0.85, 0.85], major = [0.69, 0.69, 0.69];
    for (var i = 0; i <= cells; i++) {
      var u = -half + i * step, c = (2 * i === cells || (i - cells / 2) % 10 === 0) ? major : minor;
      for (var j = 0; j < cells; j++) {
        var a = -half + j * step, b = a + step;
        xyz.push(u, 0, a, u, 0, b, a, 0, u, b, 0, u);
        for (var k = 0; k < 4; k++) colours.push(c[0], c[1], c[2]);
      }
    }
    var g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.Float32BufferAttribute(xyz, 3));
    g.setAttribute("color", new THREE.Float32BufferAttribute(colours, 3));
    return new THREE.LineSegments(g, new THREE.LineBasicMaterial({ vertexColors: true }));
  }

  function shapeMesh(s, material) {
    var g;
    if (s.kind === "box") g = new THREE.BoxGeometry(s.size[0], s.size[1], s.size[2]);
    else if (s.kind === "sphere") g = new THREE.SphereGeometry(s.size[0], 24, 16);
    else if (s.kind === "cylinder") g = new THREE.CylinderGeometry(s.size[0], s.size[0], s.size[1], 32);
    else if (s.kind === "capsule") g = new THREE.CapsuleGeometry(s.size[0], s.size[1], 8, 16);
    else {  // a mesh: its triangles
      g = new THREE.BufferGeometry();
      g.setAttribute("position", new THREE.Float32BufferAttribute(s.vertices, 3));
      g.setIndex(s.faces);
      g.computeVertexNormals();
    }
    var inner = new THREE.Mesh(g, s.colour && s.solid ? new THREE.MeshStandardMaterial({ color: s.colour }) : material);
    if (s.kind === "cylinder" || s.kind === "capsule") inner.rotation.x = Math.PI / 2;  // three's y axis -> z
    var outer = new THREE.Group(), r = s.rotation, o = s.origin;
    outer.matrixAutoUpdate = false;
    outer.matrix.set(r[0], r[1], r[2], o[0], r[3], r[4], r[5], o[1], r[6], r[7], r[8], o[2], 0, 0, 0, 1);
    outer.add(inner);
    return outer;
  }

  function Viewer(root, data) {
    this.root = root; this.data = data; this.frame = 0; this.playing = false; this.speed = 1;
    this.show = { force: true, moment: true, trails: true, frames: true };
    var size = data.follow ? data.extent : data.size;  // the scale of pins, arrows and the grid
    this.size = size;
    this.times = data.t;
    var canvasBox = document.createElement("div");
    canvasBox.className = "appell-viewer-canvas";
    root.appendChild(canvasBox);
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    this.renderer.setClearColor(0xffffff, 1);
    canvasBox.appendChild(this.renderer.domElement);
    var scene = this.scene = new THREE.Scene();
    scene.add(new THREE.HemisphereLight(0xffffff, 0x888888, 2.2));
    var sun = new THREE.DirectionalLight(0xffffff, 1.6);
    var B = basis(data.up);
    sun.position.copy(B[0].clone().add(B[1].clone().multiplyScalar(-0.7)).add(B[2].clone().multiplyScalar(1.5)));
    scene.add(sun);
    var lo = new THREE.Vector3().fromArray(data.bounds[0]), hi = new THREE.Vector3().fromArray(data.bounds[1]);
    var centre = lo.clone().add(hi).multiplyScalar(0.5);
    this.centre = centre;
    // the ground (3-D) or a grid in the plane of the motion (2-D)
    var normal = data.plane ? new THREE.Vector3().fromArray(data.plane) : B[2];
    // cells of a power of ten near a quarter of the mechanism; a followed mechanism carries a
    // grid of 8 sizes with it, moved by whole cells so that its lines stay put in the world
    var step = Math.pow(10, Math.floor(Math.log10(size / 4)));
    var cells = 2 * Math.ceil((data.follow ? 4 * size : 1.6 * data.size) / step);
    this.step = step;
    if (data.ground || data.plane) {
      var grid = gridLines(cells, step);
      grid.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), normal);
      var height = Math.min(lo.dot(normal), hi.dot(normal));
      if (data.plane) height -= 0.02 * size;  // behind the motion
      else {  // under the lowest point of the scene, at most at the origin's level
        height = 0;
        for (var c = 0; c < 8; c++) {
          var corner = new THREE.Vector3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z);
          height = Math.min(height, corner.dot(normal));
        }
      }
      var middle = centre.clone().sub(normal.clone().multiplyScalar(centre.dot(normal)));
      middle.set(Math.round(middle.x / step) * step, Math.round(middle.y / step) * step, Math.round(middle.z / step) * step);
      middle.sub(normal.clone().multiplyScalar(middle.dot(normal)));
      grid.position.copy(middle).add(normal.clone().multiplyScalar(height));
      scene.add(grid);
      this.grid = grid; this.normal = normal; this.height = height;
      if (!data.plane) {  // the ground as a surface under its lines
        var floor = new THREE.Mesh(new THREE.PlaneGeometry(cells * step, cells * step),
                                   new THREE.MeshBasicMaterial({ color: 0xf2f2f2, side: THREE.DoubleSide, depthWrite: false }));
        floor.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), normal);
        floor.position.copy(grid.position).sub(normal.clone().multiplyScalar(1e-3 * size));
        floor.renderOrder = -1;
        scene.add(floor);
        this.floor = floor;
      }
    }
    // bodies
    var meshes = 0, thick = Math.min(0.025 * (data.detail || size), 0.012 * size);
    this.bodies = data.bodies.map(function (b, k) {
      var colour = PALETTE[k % PALETTE.length];
      var material = new THREE.MeshStandardMaterial({ color: colour, metalness: 0.1, roughness: 0.6 });
      var group = new THREE.Group();
      var ghost = new THREE.MeshStandardMaterial({ color: colour, transparent: true, opacity: 0.28, depthWrite: false });
      b.shapes.forEach(function (s) { group.add(shapeMesh(s, s.solid ? material : ghost)); meshes++; });
      var solid = b.shapes.some(function (s) { return s.solid; });
      if (!solid) {
        if (b.particle) { group.add(new THREE.Mesh(new THREE.SphereGeometry(3 * thick, 20, 14), material)); meshes++; }
        else {
          var links = b.links.length ? b.links : [[0, 0, 0]], a = new THREE.Vector3().fromArray(links[0]);
          var ends = links.slice(1);
          if (!ends.length) ends = [b.com];
          ends.forEach(function (e) {
            var other = new THREE.Vector3().fromArray(e);
            if (other.distanceTo(a) > 1e-9 * size) { group.add(bar(a, other, thick, material)); meshes++; }
          });
          links.forEach(function (p) {
            var pin = new THREE.Mesh(new THREE.SphereGeometry(1.8 * thick, 16, 10),
                                     new THREE.MeshStandardMaterial({ color: 0x333333 }));
            pin.position.fromArray(p); group.add(pin); meshes++;
          });
          var dot = new THREE.Mesh(new THREE.SphereGeometry(2.6 * thick, 16, 10), material);
          dot.position.fromArray(b.com); group.add(dot); meshes++;
        }
      }
      if (b.joint) {  // the joint's frame: the child's axes at the joint (x red, y green, z blue)
        var axes = new THREE.AxesHelper(Math.max(6 * thick, 0.15 * (data.detail || size)));
        axes.position.fromArray(b.joint); axes.material.depthTest = false; axes.renderOrder = 5;
        axes.name = "frame"; group.add(axes);
      }
      scene.add(group);
      return { data: b, group: group };
    });
    // arrows: the largest of each kind is 40 % of the scene
    var reference = 0.4 * size;
    this.arrows = data.arrows.map(function (a) {
      var helper = arrow(KIND_COLOUR[a.kind], 0.006 * size, a.kind === "moment");
      scene.add(helper); meshes++;
      return { data: a, helper: helper, scale: data.scale[a.kind] > 0 ? reference / data.scale[a.kind] : 0 };
    });
    this.trails = data.trails.map(function (tr) {
      var g = new THREE.BufferGeometry();
      g.setAttribute("position", new THREE.Float32BufferAttribute(tr.p, 3));
      var line = new THREE.Line(g, new THREE.LineBasicMaterial({ color: 0x555555 }));
      scene.add(line); meshes++;
      return line;
    });
    this.meshes = meshes;
    // the camera: along the normal of a planar motion, else from above at an angle
    var aspect = 1.6;
    if (data.plane) {
      var d = 4 * size, up = new THREE.Vector3().fromArray(data.up);
      up.sub(normal.clone().multiplyScalar(up.dot(normal)));
      if (up.length() < 1e-6) up = Math.abs(normal.y) < 0.9 ? new THREE.Vector3(0, 1, 0) : new THREE.Vector3(0, 0, 1);
      this.camera = new THREE.OrthographicCamera(-1, 1, 1, -1, 0.01 * d, 100 * d);
      this.camera.up.copy(up.normalize());
      this.camera.position.copy(centre).add(normal.clone().multiplyScalar(d));
      this.halfHeight = (data.follow ? 0.9 : 0.62) * size;
    } else {
      this.camera = new THREE.PerspectiveCamera(40, aspect, 0.01 * size, 200 * size);
      this.camera.up.copy(B[2]);
      var dir = B[0].clone().multiplyScalar(0.75).add(B[1].clone().multiplyScalar(-1.0)).add(B[2].clone().multiplyScalar(0.6));
      this.camera.position.copy(centre).add(dir.normalize().multiplyScalar(1.7 * size));
    }
    if (data.follow) {  // the camera looks at the mechanism where it is
      var c0 = vec(data.centre, 0);
      this.camera.position.add(c0.clone().sub(centre));
      centre = c0;
      this.target = c0.clone();
    }
    this.camera.lookAt(centre);
    this.controls = new THREE.OrbitControls(this.camera, this.renderer.domElement);
    this.controls.target.copy(centre);
    this.controls.update();  // the constructor turned the camera to its default target, the origin
    if (data.plane) this.controls.enableRotate = false;
    var self = this;
    this.controls.addEventListener("change", function () { self.dirty = true; });
    this.toolbar();
    this.resize();
    if (window.ResizeObserver) new ResizeObserver(function () { self.resize(); }).observe(root);
    document.addEventListener("appell-seek", function (e) { self.pause(); self.setTime(e.detail.t, true); });
    this.setFrame(0);
  }

  Viewer.prototype.toolbar = function () {
    var self = this, bar = document.createElement("div");
    bar.className = "appell-viewer-bar";
    this.button = document.createElement("button"); this.button.type = "button"; this.button.textContent = "▶ play";
    this.button.onclick = function () { self.playing ? self.pause() : self.play(); };
    this.slider = document.createElement("input");
    this.slider.type = "range"; this.slider.min = 0; this.slider.max = this.times.length - 1; this.slider.value = 0;
    this.slider.setAttribute("aria-label", "time");
    this.slider.oninput = function () { self.pause(); self.setFrame(+self.slider.value, true); };
    this.label = document.createElement("span"); this.label.className = "appell-viewer-time";
    var speed = document.createElement("select");
    [0.25, 0.5, 1, 2, 4].forEach(function (s) {
      var o = document.createElement("option"); o.value = s; o.textContent = s + "×"; if (s === 1) o.selected = true; speed.appendChild(o);
    });
    speed.onchange = function () { self.speed = +speed.value; };
    speed.setAttribute("aria-label", "playback speed");
    bar.append(this.button, this.slider, this.label, speed);
    this.status = document.createElement("span"); this.status.className = "appell-viewer-states";
    if (this.data.states && this.data.states.length) bar.appendChild(this.status);
    var kinds = {};
    this.data.arrows.forEach(function (a) { if (self.data.scale[a.kind] > 0) kinds[a.kind] = true; });
    var names = { force: "forces", moment: "moments", trails: "paths", frames: "joint frames" };
    var extra = (this.data.trails.length ? ["trails"] : []).concat(
      this.data.bodies.some(function (b) { return b.joint; }) ? ["frames"] : []);
    Object.keys(kinds).concat(extra).forEach(function (k) {
      var box = document.createElement("label"), check = document.createElement("input");
      check.type = "checkbox"; check.checked = true;
      check.onchange = function () { self.show[k] = check.checked; self.setFrame(self.frame); };
      box.append(check, " " + names[k]);
      if (KIND_COLOUR[k] !== undefined) box.style.color = "#" + KIND_COLOUR[k].toString(16).padStart(6, "0");
      bar.appendChild(box);
    });
    this.root.appendChild(bar);
    var legend = document.createElement("div"); legend.className = "appell-viewer-legend";
    var parts = [];
    ["force", "moment"].forEach(function (k) {
      var largest = self.data.scale[k];
      if (largest > 0) parts.push(names[k] + ": the longest arrow is " + largest.toPrecision(3) + (k === "force" ? " N" : " N·m"));
    });
    if (this.data.note) parts.push(this.data.note);
    legend.textContent = parts.join(" · ");
    this.root.appendChild(legend);
  };

  Viewer.prototype.resize = function () {
    var width = Math.max(this.root.clientWidth, 200), height = Math.round(Math.min(520, Math.max(240, 0.6 * width)));
    this.renderer.setSize(width, height);
    var aspect = width / height, c = this.camera;
    if (c.isOrthographicCamera) {
      var h = this.halfHeight;
      c.left = -h * aspect; c.right = h * aspect; c.top = h; c.bottom = -h;
    } else c.aspect = aspect;
    c.updateProjectionMatrix();
    this.dirty = true;
  };

  Viewer.prototype.setFrame = function (k, announce) {
    var self = this, n = this.times.length;
    k = Math.max(0, Math.min(n - 1, k | 0));
    this.frame = k;
    this.bodies.forEach(function (b) {
      var p = b.data.p, q = b.data.q;
      b.group.position.set(p[3 * k], p[3 * k + 1], p[3 * k + 2]);
      b.group.quaternion.set(q[4 * k + 1], q[4 * k + 2], q[4 * k + 3], q[4 * k]);
    });
    this.arrows.forEach(function (a) {
      var v = vec(a.data.v, k), len = v.length() * a.scale, h = a.helper;
      h.visible = self.show[a.data.kind] && len > 1e-6 * self.size;  // a released contact has none
      if (!h.visible) return;
      h.position.copy(vec(a.data.at, k));
      h.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), v.normalize());
      h.userData.setLength(len, Math.min(0.3 * len, 0.05 * self.size));
    });
    if (this.data.follow && this.controls) {
      var c = vec(this.data.centre, k), shift = c.clone().sub(this.controls.target);
      this.camera.position.add(shift); this.controls.target.copy(c); this.controls.update();
      if (this.grid) {
        var n = this.normal, st = this.step, m = c.clone().sub(n.clone().multiplyScalar(c.dot(n)));
        m.set(Math.round(m.x / st) * st, Math.round(m.y / st) * st, Math.round(m.z / st) * st);
        m.sub(n.clone().multiplyScalar(m.dot(n))).add(n.clone().multiplyScalar(this.height));
        var moved = m.clone().sub(this.grid.position);
        this.grid.position.copy(m);
        if (this.floor) this.floor.position.add(moved);
      }
    }
    this.trails.forEach(function (line) { line.visible = self.show.trails; line.geometry.setDrawRange(0, k + 1); });
    this.bodies.forEach(function (b) { var f = b.group.getObjectByName("frame"); if (f) f.visible = self.show.frames; });
    if (this.data.states && this.data.states.length) {  // contacts: slipping or sticking, touching or released
      this.status.textContent = this.data.states.map(function (st) {
        return st.name + ": " + st.labels[st.values[k]];
      }).join(" · ");
      this.root.setAttribute("data-viewer-states", this.status.textContent);
    }
    this.slider.value = k;
    this.label.textContent = "t = " + this.times[k].toFixed(3) + " s";
    this.dirty = true;
    if (announce !== false) document.dispatchEvent(new CustomEvent("appell-time", { detail: { t: this.times[k], source: this } }));
  };

  Viewer.prototype.setTime = function (t, announce) {
    this.clock = t;
    this.setFrame(frameAt(this.times, t + 1e-12), announce);
  };

  Viewer.prototype.play = function () {
    if (this.frame >= this.times.length - 1) this.setFrame(0);
    this.playing = true; this.clock = this.times[this.frame]; this.last = null; this.button.textContent = "❚❚ pause";
  };

  Viewer.prototype.pause = function () { this.playing = false; this.button.textContent = "▶ play"; };

  Viewer.prototype.tick = function (now) {
    if (this.playing) {
      if (this.last !== null) {
        this.clock += this.speed * (now - this.last) / 1000;
        if (this.clock >= this.times[this.times.length - 1]) { this.setTime(this.times[this.times.length - 1]); this.pause(); }
        else this.setTime(this.clock);
      }
      this.last = now;
    }
    if (this.dirty) { this.renderer.render(this.scene, this.camera); this.dirty = false; }
  };

  // frames per second of playing: each frame set, rendered and read back (one pixel, which
  // waits for the drawing to finish: no frame is counted before it is on the canvas)
  Viewer.prototype.bench = function (count) {
    var gl = this.renderer.getContext(), pixel = new Uint8Array(4), start = performance.now();
    for (var i = 0; i < count; i++) {
      this.setFrame(i % this.times.length, false);
      this.renderer.render(this.scene, this.camera);
      gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
    }
    return count / ((performance.now() - start) / 1000);
  };

  function start(root) {
    var source = document.getElementById(root.getAttribute("data-scene"));
    try {
      if (typeof THREE === "undefined") throw new Error("three.js is missing");
      var probe = document.createElement("canvas");
      if (!(probe.getContext("webgl2") || probe.getContext("webgl"))) {
        root.setAttribute("data-viewer", "no-webgl");
        root.textContent = "This browser cannot draw WebGL: the 3-D view is not shown (the plots show the motion).";
        return null;
      }
      var viewer = new Viewer(root, JSON.parse(source.textContent));
      var hash = {};
      (window.location.hash || "").replace(/^#/, "").split("&").forEach(function (kv) {
        var p = kv.split("="); if (p[0]) hash[p[0]] = decodeURIComponent(p[1] || "");
      });
      if (hash.t !== undefined) viewer.setTime(parseFloat(hash.t));
      if (hash.bench !== undefined) root.setAttribute("data-viewer-fps", viewer.bench(parseInt(hash.bench, 10) || 300).toFixed(1));
      viewer.renderer.render(viewer.scene, viewer.camera); viewer.dirty = false;
      root.setAttribute("data-viewer", "ready");
      root.setAttribute("data-viewer-frames", viewer.times.length);
      root.setAttribute("data-viewer-meshes", viewer.meshes);
      root.setAttribute("data-viewer-frame", viewer.frame);
      return viewer;
    } catch (err) {
      root.setAttribute("data-viewer", "error: " + err.message);
      var box = document.createElement("p"); box.className = "appell-viewer-error";
      box.textContent = "The view could not be drawn: " + err.message;
      root.appendChild(box);
      return null;
    }
  }

  function startAll() {
    var viewers = [];
    document.querySelectorAll(".appell-viewer").forEach(function (root) {
      if (root.getAttribute("data-viewer")) return;
      var v = start(root); if (v) viewers.push(v);
    });
    var states = [];
    document.querySelectorAll(".appell-viewer").forEach(function (r) { states.push(r.getAttribute("data-viewer")); });
    document.body.setAttribute("data-viewers", states.join(";"));
    function loop(now) { viewers.forEach(function (v) { v.tick(now); }); requestAnimationFrame(loop); }
    if (viewers.length) requestAnimationFrame(loop);
  }

  if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", startAll);
  else startAll();
})();
