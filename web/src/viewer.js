// 3-D playback: the model's bone meshes (when its geometry is found; else bones as lines between
// body origins), centres of mass, model and measured markers, the ground and the ground reaction
// forces. The camera starts at the subject's right side, framing the whole body, and follows the pelvis.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';

const GRF_M_PER_N = 0.001;  // 1 mm of arrow per newton

// A mesh file's triangles ({positions, triangles}) placed as the model attaches it (m: file, scale,
// translation, rotation in the body).
function boneMesh(data, m, material) {
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(data.positions), 3));
  geometry.setIndex(data.triangles);
  geometry.computeVertexNormals();
  const mesh = new THREE.Mesh(geometry, material);
  mesh.scale.set(...m.scale);
  mesh.position.set(...m.translation);
  mesh.quaternion.set(...m.rotation);
  return mesh;
}

// Whether WebGL runs on a software rasteriser (SwiftShader, llvmpipe: a machine without a GPU), where
// antialiasing doubles every frame's time (a 55k-triangle skeleton: 67 ms against 33 ms here).
function softwareRenderer() {
  const gl = document.createElement('canvas').getContext('webgl');
  if (!gl) return false;
  const info = gl.getExtension('WEBGL_debug_renderer_info');
  const name = String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER));
  const lose = gl.getExtension('WEBGL_lose_context');
  if (lose) lose.loseContext();
  return /swiftshader|llvmpipe|softpipe|software/i.test(name);
}

const SPHERE = new THREE.SphereGeometry(1, 12, 8);

// Small spheres of one colour and radius (markers, joints, centres of mass) in one draw call:
// place(i, [x, y, z]) moves one, place(i, null) hides it; positions keeps where each is.
class Dots extends THREE.InstancedMesh {
  constructor(count, radius, color) {
    super(SPHERE, new THREE.MeshLambertMaterial({ color }), Math.max(1, count));
    this.count = count;
    this.radius = radius;
    this.frustumCulled = false;
    this.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
    this.positions = Array.from({ length: count }, () => new THREE.Vector3());
    this.matrix4 = new THREE.Matrix4();
    for (let i = 0; i < count; ++i) this.place(i, null);
  }

  place(i, p) {
    if (p) this.positions[i].set(p[0], p[1], p[2]);
    this.matrix4.makeScale(...(p ? [this.radius, this.radius, this.radius] : [0, 0, 0])).setPosition(this.positions[i]);
    this.setMatrixAt(i, this.matrix4);
    this.instanceMatrix.needsUpdate = true;
  }
}

export class Viewer {
  constructor(container, kin) {
    this.kin = kin;
    this.software = softwareRenderer();
    this.renderer = new THREE.WebGLRenderer({ antialias: !this.software, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    container.appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0x0f172a);
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.01, 100);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x334155, 1.2));
    const grid = new THREE.GridHelper(20, 40, 0x475569, 0x1e293b);
    this.scene.add(grid);

    const names = kin.bodies.map((b) => b.name);
    this.parentIndex = kin.bodies.map((b) => names.indexOf(b.parent));  // -1: ground
    this.hasChild = kin.bodies.map((_, i) => this.parentIndex.includes(i));
    this.joints = this.add(new Dots(kin.bodies.length, 0.025, 0xe2e8f0));
    this.coms = this.add(new Dots(kin.bodies.length, 0.015, 0xfacc15));
    this.modelMarkers = this.add(new Dots(kin.model_marker_names.length, 0.012, 0x60a5fa));
    this.measuredMarkers = this.add(new Dots(kin.measured_marker_names.length, 0.012, 0xfb923c));
    this.bones = new THREE.LineSegments(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color: 0xe2e8f0 }));
    this.bones.geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(kin.bodies.length * 6), 3));
    this.scene.add(this.bones);
    this.arrows = [];
    // Bone meshes: one group per body, posed each frame; filled by loadMeshes.
    this.boneGroups = kin.bodies.map(() => { const g = new THREE.Group(); this.scene.add(g); return g; });
    this.meshCount = 0;
    this.boneMode = 'lines';
    // Muscles: every path segment a thin cylinder (one instanced mesh), coloured by activation.
    const segments = Math.max(1, ...kin.frames.map((f) => (f.muscles || []).reduce((n, p) => n + Math.max(0, p.length / 3 - 1), 0)));
    const tube = new THREE.CylinderGeometry(1, 1, 1, 6, 1, true).translate(0, 0.5, 0);
    this.muscles = new THREE.InstancedMesh(tube, new THREE.MeshLambertMaterial({ color: 0xffffff }), segments);
    this.muscles.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
    this.muscles.count = 0;
    this.muscles.frustumCulled = false;
    this.scene.add(this.muscles);
    this.activation = null;  // (frameIndex, muscleIndex) -> 0..1, or null: set by setActivation
    this.meshData = new Map();  // mesh file -> promise of its triangles (shared with the overlay)
    this.overlay = null;
    // Progression: where the pelvis went over the trial; on a treadmill, against the belt (+x when
    // neither says).
    const first = kin.frames[0].bodies[0], last = kin.frames[kin.frames.length - 1].bodies[0];
    this.forward = new THREE.Vector3(last[0] - first[0], 0, last[2] - first[2]);
    if (kin.treadmill) this.forward.set(-kin.treadmill.belt_velocity_m_s[0], 0, -kin.treadmill.belt_velocity_m_s[2]);
    if (this.forward.length() < 0.2) this.forward.set(1, 0, 0);
    this.forward.normalize();
    this.belt = kin.treadmill ? this.addBelt(kin.treadmill, first) : null;
    // The subject's height at the first frame (highest body origin plus a head) sets the framing.
    this.height = Math.max(1.0, ...kin.frames[0].bodies.map((b) => b[1])) + 0.3;
    this.resize = () => {
      const w = container.clientWidth, h = container.clientHeight;
      this.renderer.setSize(w, h, false);
      this.camera.aspect = w / Math.max(h, 1);
      this.camera.updateProjectionMatrix();
      this.render();
    };
    new ResizeObserver(this.resize).observe(container);
    this.controls.addEventListener('change', () => this.render());
    this.setView('side');
    this.resize();
  }

  // A treadmill belt under the subject (centred on the first frame's pelvis), its stripes moving
  // with the belt's velocity (m/s in ground): showBelt places them at a time.
  addBelt(treadmill, pelvis) {
    const v = treadmill.belt_velocity_m_s, speed = Math.hypot(v[0], v[2]);
    const canvas = document.createElement('canvas');
    canvas.width = 64; canvas.height = 8;
    const g = canvas.getContext('2d');
    g.fillStyle = '#334155'; g.fillRect(0, 0, 64, 8);
    g.fillStyle = '#94a3b8'; g.fillRect(0, 0, 8, 8);
    const texture = new THREE.CanvasTexture(canvas);
    texture.wrapS = texture.wrapT = THREE.RepeatWrapping;
    const length = 2.4, width = 0.8, period = 0.2;  // m
    texture.repeat.set(length / period, 1);
    // Local x along the belt's motion, lying flat at the ground's height.
    const mesh = new THREE.Mesh(new THREE.PlaneGeometry(length, width).rotateX(-Math.PI / 2),
      new THREE.MeshBasicMaterial({ map: texture, transparent: true, opacity: 0.85 }));
    mesh.position.set(pelvis[0], treadmill.height_m + 0.001, pelvis[2]);
    mesh.rotation.y = Math.atan2(-v[2], v[0]);
    this.scene.add(mesh);
    return { mesh, texture, speed, period };
  }

  // Stripes where the belt has carried them after t seconds: a pattern moved by d along the belt's
  // motion shows at u what was at u - d.
  showBelt(t) {
    const b = this.belt;
    const offset = -(b.speed * t) / b.period;
    b.texture.offset.x = offset - Math.floor(offset);
  }

  // side (from the subject's right), front or top, at a distance that frames the whole body.
  setView(kind) {
    const f = this.kin.frames[0].bodies[0];
    // The figure as drawn now (its meshes, else its joints up to a head above the highest one).
    const box = new THREE.Box3();
    if (this.boneMode === 'meshes') this.boneGroups.forEach((g) => box.expandByObject(g));
    if (box.isEmpty()) {
      this.kin.frames[0].bodies.forEach((b) => box.expandByPoint(new THREE.Vector3(b[0], b[1], b[2])));
      box.expandByPoint(new THREE.Vector3(f[0], this.height, f[2])).expandByPoint(new THREE.Vector3(f[0], 0, f[2]));
    }
    const height = Math.max(1.0, box.max.y - Math.min(0, box.min.y));
    const target = new THREE.Vector3(f[0], (box.max.y + Math.min(0, box.min.y)) / 2, f[2]);
    const distance = (0.62 * height) / Math.tan((this.camera.fov * Math.PI) / 360);
    const right = new THREE.Vector3().crossVectors(this.forward, new THREE.Vector3(0, 1, 0)).normalize();
    const dir = kind === 'front' ? this.forward.clone() : kind === 'top' ? new THREE.Vector3(0, 1, 0).addScaledVector(this.forward, -0.001) : right;
    this.controls.target.copy(target);
    this.camera.position.copy(target).addScaledVector(dir.normalize(), distance);
    this.controls.update();
    this.view = kind;
    this.render();
  }

  // Fetches each body's meshes (fetchMesh(file) -> {positions, triangles} or null) and shows them
  // instead of the lines; returns how many were drawn.
  async loadMeshes(fetchMesh) {
    const material = new THREE.MeshLambertMaterial({ color: 0xe8e1cf });
    const cache = this.meshData;
    await Promise.all(this.kin.bodies.map(async (b, i) => {
      for (const m of b.meshes || []) {
        if (!cache.has(m.file)) cache.set(m.file, fetchMesh(m.file));
        const data = await cache.get(m.file);
        if (!data) continue;
        this.boneGroups[i].add(boneMesh(data, m, material));
        this.meshCount++;
      }
    }));
    this.setBoneMode(this.meshCount ? 'meshes' : 'lines');
    this.show(0);
    this.setView(this.view);
    return this.meshCount;
  }

  // A second, translucent figure on the same timeline (the reproduced gait over the measured one):
  // kin2's frames are matched to this trial's by time; the figure hides where kin2 has no frame.
  addOverlay(kin2, label) {
    const material = new THREE.MeshLambertMaterial({ color: 0x38bdf8, transparent: true, opacity: 0.45, depthWrite: false });
    const groups = kin2.bodies.map(() => { const g = new THREE.Group(); this.scene.add(g); return g; });
    kin2.bodies.forEach((b, i) => {
      for (const m of b.meshes || []) {
        const data = this.meshData.get(m.file);
        if (!data) continue;
        data.then((d) => {
          if (!d) return;
          groups[i].add(boneMesh(d, m, material));
          this.render();
        });
      }
    });
    // Without meshes: its bones as lines.
    const lines = new THREE.LineSegments(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color: 0x38bdf8, transparent: true, opacity: 0.8 }));
    lines.geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(kin2.bodies.length * 6), 3));
    this.scene.add(lines);
    const names = kin2.bodies.map((b) => b.name), parent = kin2.bodies.map((b) => names.indexOf(b.parent));
    let j = 0;  // both in time order: one pass
    const frameAt = this.kin.frames.map((f) => {
      while (j < kin2.frames.length && kin2.frames[j].time < f.time - 1e-6) j++;
      return j < kin2.frames.length && Math.abs(kin2.frames[j].time - f.time) < 1e-6 ? j : -1;
    });
    this.overlay = { kin: kin2, label, groups, lines, parent, frameAt, visible: true };
    if (this.frameIndex != null) this.show(this.frameIndex);
  }

  setOverlayVisible(visible) {
    this.overlay.visible = visible;
    this.show(this.frameIndex);
  }

  // Whether the overlay's figure is drawn at this frame.
  overlayShownAt(frameIndex) {
    return !!this.overlay && this.overlay.visible && this.overlay.frameAt[frameIndex] >= 0;
  }

  showOverlay(frameIndex) {
    const o = this.overlay;
    const k = o.frameAt[frameIndex];
    const g = k >= 0 && o.visible ? o.kin.frames[k] : null;
    const meshes = o.groups.some((grp) => grp.children.length);
    o.groups.forEach((grp, i) => {
      grp.visible = !!g && meshes;
      if (g) { const p = g.bodies[i]; grp.position.set(p[0], p[1], p[2]); grp.quaternion.set(p[3], p[4], p[5], p[6]); }
    });
    o.lines.visible = !!g && !meshes;
    if (g) {
      const pos = o.lines.geometry.attributes.position;
      g.bodies.forEach((p, i) => {
        const a = o.parent[i] >= 0 ? g.bodies[o.parent[i]] : p;
        pos.setXYZ(2 * i, a[0], a[1], a[2]);
        pos.setXYZ(2 * i + 1, p[0], p[1], p[2]);
      });
      pos.needsUpdate = true;
      o.lines.geometry.computeBoundingSphere();
    }
  }

  // Muscle colours follow activation(frameIndex, muscleIndex) in 0..1 (grey-blue at rest, red at 1).
  setActivation(activation) {
    this.activation = activation;
    if (this.frameIndex != null) this.show(this.frameIndex);
  }

  setMusclesVisible(visible) {
    this.muscles.visible = visible;
    this.render();
  }

  showMuscles(f, frameIndex) {
    const up = new THREE.Vector3(0, 1, 0), a = new THREE.Vector3(), d = new THREE.Vector3(), q = new THREE.Quaternion();
    const scale = new THREE.Vector3(), m = new THREE.Matrix4(), rest = new THREE.Color(0x64748b), full = new THREE.Color(0xef4444), c = new THREE.Color();
    let k = 0;
    (f.muscles || []).forEach((pts, i) => {
      const act = this.activation ? Math.max(0, Math.min(1, this.activation(frameIndex, i) || 0)) : 0.15;
      c.copy(rest).lerp(full, act);
      for (let j = 0; j + 5 < pts.length; j += 3) {
        a.set(pts[j], pts[j + 1], pts[j + 2]);
        d.set(pts[j + 3] - pts[j], pts[j + 4] - pts[j + 1], pts[j + 5] - pts[j + 2]);
        const length = d.length();
        if (length < 1e-6) continue;
        q.setFromUnitVectors(up, d.multiplyScalar(1 / length));
        m.compose(a, q, scale.set(0.005, length, 0.005));
        this.muscles.setMatrixAt(k, m);
        this.muscles.setColorAt(k, c);
        k++;
      }
    });
    this.muscles.count = k;
    this.muscles.instanceMatrix.needsUpdate = true;
    if (this.muscles.instanceColor) this.muscles.instanceColor.needsUpdate = true;
  }

  // 'meshes': the bone meshes; 'lines': the stick figure (joints and bones between body origins).
  setBoneMode(mode) {
    this.boneMode = mode === 'meshes' && this.meshCount ? 'meshes' : 'lines';
    const meshes = this.boneMode === 'meshes';
    this.boneGroups.forEach((g) => { g.visible = meshes; });
    this.bones.visible = !meshes;
    this.joints.visible = !meshes;
    this.render();
  }

  // The drawn figure's extent on screen (normalised device coordinates, -1..1 inside the canvas).
  figureScreenBounds() {
    const box = new THREE.Box3();
    if (this.boneMode === 'meshes') this.boneGroups.forEach((g) => box.expandByObject(g));
    else this.joints.positions.forEach((p) => box.expandByPoint(p));
    const min = [Infinity, Infinity], max = [-Infinity, -Infinity];
    for (const x of [box.min.x, box.max.x]) for (const y of [box.min.y, box.max.y]) for (const z of [box.min.z, box.max.z]) {
      const p = new THREE.Vector3(x, y, z).project(this.camera);
      min[0] = Math.min(min[0], p.x); min[1] = Math.min(min[1], p.y); max[0] = Math.max(max[0], p.x); max[1] = Math.max(max[1], p.y);
    }
    return { min, max };
  }

  add(object) {
    this.scene.add(object);
    return object;
  }

  show(frameIndex) {
    const f = this.kin.frames[frameIndex];
    if (!f) return;
    this.frameIndex = frameIndex;
    this.showMuscles(f, frameIndex);
    if (this.overlay) this.showOverlay(frameIndex);
    if (this.belt) this.showBelt(f.time);
    const pos = this.bones.geometry.attributes.position;
    f.bodies.forEach((p, i) => {
      this.joints.place(i, p);
      this.boneGroups[i].position.set(p[0], p[1], p[2]);
      this.boneGroups[i].quaternion.set(p[3], p[4], p[5], p[6]);
      this.coms.place(i, f.com[i]);
      // A bone from the parent's origin to this body's; a leaf body also points through its COM.
      const parent = this.parentIndex[i] >= 0 ? f.bodies[this.parentIndex[i]] : p;
      const end = this.hasChild[i] || this.parentIndex[i] < 0 ? p : [2 * f.com[i][0] - p[0], 2 * f.com[i][1] - p[1], 2 * f.com[i][2] - p[2]];
      const a = this.hasChild[i] || this.parentIndex[i] < 0 ? parent : p;
      pos.setXYZ(2 * i, a[0], a[1], a[2]);
      pos.setXYZ(2 * i + 1, end[0], end[1], end[2]);
    });
    pos.needsUpdate = true;
    this.bones.geometry.computeBoundingSphere();
    f.model_markers.forEach((p, i) => this.modelMarkers.place(i, p));
    f.measured_markers.forEach((p, i) => this.measuredMarkers.place(i, p));
    this.arrows.forEach((a) => this.scene.remove(a));
    this.arrows = (f.grf || []).filter((g) => Math.hypot(...g.force) > 5).map((g) => {
      const v = new THREE.Vector3(...g.force);
      const a = new THREE.ArrowHelper(v.clone().normalize(), new THREE.Vector3(...g.point), v.length() * GRF_M_PER_N, 0x22c55e, 0.05, 0.03);
      this.scene.add(a);
      return a;
    });
    // Follow the walker along the ground.
    const root = f.bodies[0];
    const dx = root[0] - this.controls.target.x, dz = root[2] - this.controls.target.z;
    this.controls.target.x += dx;
    this.controls.target.z += dz;
    this.camera.position.x += dx;
    this.camera.position.z += dz;
    this.controls.update();
    this.render();
  }

  render() {
    this.renderer.render(this.scene, this.camera);
  }
}
