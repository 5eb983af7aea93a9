// 3-D playback: bones between body origins, centres of mass, model and measured markers, the
// ground and the ground reaction forces. Geometry-free on purpose: it shows what the model did.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';

const GRF_M_PER_N = 0.001;  // 1 mm of arrow per newton

export class Viewer {
  constructor(container, kin) {
    this.kin = kin;
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    container.appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0x0f172a);
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.01, 100);
    this.camera.position.set(0.9, 1.25, 2.3);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.target.set(0, 0.9, 0);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x334155, 1.2));
    const grid = new THREE.GridHelper(20, 40, 0x475569, 0x1e293b);
    this.scene.add(grid);

    const names = kin.bodies.map((b) => b.name);
    this.parentIndex = kin.bodies.map((b) => names.indexOf(b.parent));  // -1: ground
    this.hasChild = kin.bodies.map((_, i) => this.parentIndex.includes(i));
    const sphere = new THREE.SphereGeometry(1, 12, 8);
    const mat = (c) => new THREE.MeshLambertMaterial({ color: c });
    this.joints = kin.bodies.map(() => this.add(new THREE.Mesh(sphere, mat(0xe2e8f0)), 0.025));
    this.coms = kin.bodies.map(() => this.add(new THREE.Mesh(sphere, mat(0xfacc15)), 0.015));
    this.modelMarkers = kin.model_marker_names.map(() => this.add(new THREE.Mesh(sphere, mat(0x60a5fa)), 0.012));
    this.measuredMarkers = kin.measured_marker_names.map(() => this.add(new THREE.Mesh(sphere, mat(0xfb923c)), 0.012));
    this.bones = new THREE.LineSegments(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color: 0xe2e8f0 }));
    this.bones.geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(kin.bodies.length * 6), 3));
    this.scene.add(this.bones);
    this.arrows = [];
    this.resize = () => {
      const w = container.clientWidth, h = container.clientHeight;
      this.renderer.setSize(w, h, false);
      this.camera.aspect = w / Math.max(h, 1);
      this.camera.updateProjectionMatrix();
      this.render();
    };
    new ResizeObserver(this.resize).observe(container);
    this.controls.addEventListener('change', () => this.render());
    this.resize();
  }

  add(mesh, radius) {
    mesh.scale.setScalar(radius);
    this.scene.add(mesh);
    return mesh;
  }

  show(frameIndex) {
    const f = this.kin.frames[frameIndex];
    if (!f) return;
    const pos = this.bones.geometry.attributes.position;
    f.bodies.forEach((p, i) => {
      this.joints[i].position.set(p[0], p[1], p[2]);
      this.coms[i].position.set(...f.com[i]);
      // A bone from the parent's origin to this body's; a leaf body also points through its COM.
      const parent = this.parentIndex[i] >= 0 ? f.bodies[this.parentIndex[i]] : p;
      const end = this.hasChild[i] || this.parentIndex[i] < 0 ? p : [2 * f.com[i][0] - p[0], 2 * f.com[i][1] - p[1], 2 * f.com[i][2] - p[2]];
      const a = this.hasChild[i] || this.parentIndex[i] < 0 ? parent : p;
      pos.setXYZ(2 * i, a[0], a[1], a[2]);
      pos.setXYZ(2 * i + 1, end[0], end[1], end[2]);
    });
    pos.needsUpdate = true;
    this.bones.geometry.computeBoundingSphere();
    f.model_markers.forEach((p, i) => this.modelMarkers[i].position.set(p[0], p[1], p[2]));
    f.measured_markers.forEach((p, i) => {
      this.measuredMarkers[i].visible = p !== null;
      if (p) this.measuredMarkers[i].position.set(p[0], p[1], p[2]);
    });
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
