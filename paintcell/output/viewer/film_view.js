// The report's 3-D film view: draws the film.glb embedded in report.html with three.js
// (three-film.min.js, global PaintcellThree). Drag to rotate, scroll to zoom, right-drag to pan;
// the pointer over the part shows the executed film there [µm], interpolated from the file's
// per-vertex _THICKNESS_UM attribute exactly as the GPU interpolates the colours.
(function () {
  'use strict';
  const T = window.PaintcellThree;

  function bytesOf(b64) {
    const s = atob(b64);
    const a = new Uint8Array(s.length);
    for (let i = 0; i < s.length; i++) a[i] = s.charCodeAt(i);
    return a.buffer;
  }

  function filmMesh(root) {
    let found = null;
    root.traverse((o) => {
      if (!found && o.isMesh && o.geometry.getAttribute('_thickness_um')) found = o;
    });
    return found;
  }

  function start(box) {
    const canvas = box.querySelector('canvas');
    const tip = box.querySelector('.film-tip');
    const status = box.querySelector('.film-status');
    const data = document.getElementById(box.dataset.glb).textContent.trim();
    let renderer;
    try {
      renderer = new T.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: false });
    } catch (e) {
      status.textContent = 'This browser cannot draw WebGL: open film.glb (in the results ' +
        'folder) in Blender or any glTF viewer.';
      return;
    }
    renderer.setPixelRatio(window.devicePixelRatio || 1);
    renderer.setClearColor(0xf4f4f4, 1);
    const scene = new T.Scene();
    const camera = new T.PerspectiveCamera(35, 1, 0.01, 100);
    const controls = new T.OrbitControls(camera, canvas);
    const ray = new T.Raycaster();
    let film = null;
    let views = {};

    function draw() { renderer.render(scene, camera); }

    function resize() {
      const w = canvas.clientWidth, h = canvas.clientHeight;
      renderer.setSize(w, h, false);
      camera.aspect = w / h;
      camera.updateProjectionMatrix();
      draw();
    }

    function frame(box3, dir) {
      const c = box3.getCenter(new T.Vector3());
      const r = Math.max(box3.getSize(new T.Vector3()).length() / 2, 1e-3);
      const d = (0.8 * r) / Math.tan((camera.fov * Math.PI) / 360);
      camera.position.copy(c).addScaledVector(dir, d);
      camera.near = d / 100;
      camera.far = d * 100;
      camera.updateProjectionMatrix();
      controls.target.copy(c);
      controls.update();
      draw();
    }

    function hover(ev) {
      if (!film) return;
      const rect = canvas.getBoundingClientRect();
      const ndc = new T.Vector2(((ev.clientX - rect.left) / rect.width) * 2 - 1,
        -((ev.clientY - rect.top) / rect.height) * 2 + 1);
      ray.setFromCamera(ndc, camera);
      const hit = ray.intersectObject(film, false)[0];
      if (!hit) { tip.hidden = true; return; }
      const th = film.geometry.getAttribute('_thickness_um');
      const b = hit.barycoord;
      const um = b.x * th.getX(hit.face.a) + b.y * th.getX(hit.face.b) + b.z * th.getX(hit.face.c);
      tip.textContent = um.toFixed(1) + ' µm';
      tip.dataset.um = String(um);
      tip.style.left = (ev.clientX - rect.left + 14) + 'px';
      tip.style.top = (ev.clientY - rect.top + 10) + 'px';
      tip.hidden = false;
    }

    new T.GLTFLoader().parse(bytesOf(data), '', (gltf) => {
      scene.add(gltf.scene);
      scene.updateMatrixWorld(true);
      film = filmMesh(gltf.scene);
      if (!film) { status.textContent = 'film.glb holds no film mesh'; return; }
      // look at the painted side: along the mean of the painted-side vertex normals
      const n = film.geometry.getAttribute('normal');
      const dir = new T.Vector3();
      for (let i = 0; i < n.count; i++) dir.x += n.getX(i), dir.y += n.getY(i), dir.z += n.getZ(i);
      dir.transformDirection(film.matrixWorld);
      if (dir.lengthSq() < 1e-12) dir.set(1, 1, 1).normalize();
      dir.add(new T.Vector3(0, 0.35, 0)).normalize();  // a little from above
      views = { part: new T.Box3().setFromObject(film), cell: new T.Box3().setFromObject(gltf.scene) };
      box.querySelectorAll('button[data-view]').forEach((btn) => {
        btn.addEventListener('click', () => frame(views[btn.dataset.view], dir));
      });
      resize();
      frame(views.part, dir);
      canvas.dataset.ready = '1';
      status.textContent = '';
    }, (err) => { status.textContent = 'film.glb could not be read: ' + err.message; });

    controls.addEventListener('change', draw);
    canvas.addEventListener('pointermove', hover);
    canvas.addEventListener('pointerleave', () => { tip.hidden = true; });
    window.addEventListener('resize', resize);
  }

  document.querySelectorAll('.film-3d').forEach(start);
})();
