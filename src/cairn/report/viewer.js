// cairn report viewer (three.js): the scene JSON (report.cpp, scene_json) drawn at one captured
// instant at a time. Reports its state into #status and document.body.dataset.viewer, so a
// headless browser test can check that it ran and drew something.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const BACKGROUND = 0x1d2630;
const scene = JSON.parse(document.getElementById('scene').textContent);
const status = document.getElementById('status');

// Positions: base64 little-endian int16 triples in centimetres (report.cpp, encode_cloud).
function decodeCloud(c) {
  const bin = atob(c.xyz);
  const bytes = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
  const ints = new Int16Array(bytes.buffer);
  const pos = new Float32Array(ints.length);
  for (let i = 0; i < ints.length; i++) pos[i] = ints[i] * scene.scale;
  return pos;
}

function points(pos, colorOf, size) {
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(pos, 3));
  const col = new Float32Array(pos.length);
  const c = new THREE.Color();
  for (let i = 0; i < pos.length / 3; i++) {
    colorOf(c, pos[3 * i + 2]);
    col.set([c.r, c.g, c.b], 3 * i);
  }
  g.setAttribute('color', new THREE.BufferAttribute(col, 3));
  return new THREE.Points(g, new THREE.PointsMaterial({ size, vertexColors: true, sizeAttenuation: true }));
}

function heightShade(zmin, zmax, base) {
  return (c, z) => {
    const t = Math.min(1, Math.max(0, (z - zmin) / Math.max(zmax - zmin, 1e-3)));
    c.setRGB(base * (0.45 + 0.55 * t), base * (0.45 + 0.55 * t), base * (0.5 + 0.5 * t));
  };
}

function gripper(g) {
  const group = new THREE.Group();
  const material = new THREE.MeshLambertMaterial({ color: g.success ? 0x2ca02c : 0xd62728, transparent: true, opacity: 0.55 });
  for (const p of g.parts) {
    const box = new THREE.Mesh(new THREE.BoxGeometry(2 * p.h[0], 2 * p.h[1], 2 * p.h[2]), material);
    const R = p.R;
    const m = new THREE.Matrix4().set(R[0], R[1], R[2], p.c[0], R[3], R[4], R[5], p.c[1], R[6], R[7], R[8], p.c[2], 0, 0, 0, 1);
    box.applyMatrix4(m);
    group.add(box);
  }
  return group;
}

function ring(x, y, z, color) {
  const m = new THREE.Mesh(new THREE.RingGeometry(0.35, 0.45, 32), new THREE.MeshBasicMaterial({ color, side: THREE.DoubleSide }));
  m.position.set(x, y, z);
  return m;
}

const el = document.getElementById('viewer');
const width = el.clientWidth || 1000, height = el.clientHeight || 560;
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setSize(width, height);
el.appendChild(renderer.domElement);
const world = new THREE.Scene();
world.background = new THREE.Color(BACKGROUND);
world.add(new THREE.AmbientLight(0xffffff, 1.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.5);
sun.position.set(5, -5, 10);
world.add(sun);
const camera = new THREE.PerspectiveCamera(45, width / height, 0.1, 500);
camera.up.set(0, 0, 1);
const controls = new OrbitControls(camera, renderer.domElement);

const layers = { map: new THREE.Group(), drone: new THREE.Group(), objects: new THREE.Group(), grasps: new THREE.Group(), targets: new THREE.Group(), truth: new THREE.Group() };
for (const g of Object.values(layers)) world.add(g);
layers.drone.visible = false;

let zmin = Infinity, zmax = -Infinity, radius = 5;
const first = scene.snapshots.length ? decodeCloud(scene.snapshots[0].map) : new Float32Array(0);
for (let i = 0; i < first.length; i += 3) {
  zmin = Math.min(zmin, first[i + 2]);
  zmax = Math.max(zmax, first[i + 2]);
  radius = Math.max(radius, Math.hypot(first[i], first[i + 1]));
}
if (scene.drone.n > 0) layers.drone.add(points(decodeCloud(scene.drone), (c) => c.setRGB(0.95, 0.8, 0.35), 0.06));
for (const g of scene.grasps) if (g.parts.length) layers.grasps.add(gripper(g));
for (const g of scene.grasps) layers.targets.add(ring(g.target[0], g.target[1], isFinite(zmin) ? zmin + 0.05 : 0, g.color));

function show(k) {
  const s = scene.snapshots[k];
  for (const name of ['map', 'objects', 'truth']) layers[name].clear();
  if (!s) return;
  layers.map.add(points(decodeCloud(s.map), heightShade(zmin, zmax, 0.8), 0.07));
  for (const o of s.objects) {
    const col = new THREE.Color(o.color);
    layers.objects.add(points(decodeCloud(o), (c) => c.copy(col), 0.06));
  }
  const dot = new THREE.SphereGeometry(0.08, 12, 8), black = new THREE.MeshBasicMaterial({ color: 0x000000 });
  for (const t of s.truth) {
    const m = new THREE.Mesh(dot, black);
    m.position.set(t[0], t[1], t[2]);
    layers.truth.add(m);
  }
}

const controlsEl = document.getElementById('controls');
const select = document.createElement('select');
scene.snapshots.forEach((s, i) => select.add(new Option(`${s.label} (t = ${s.time.toFixed(0)} s)`, i)));
select.onchange = () => show(Number(select.value));
controlsEl.append('Instant: ', select);
for (const [name, group] of Object.entries(layers)) {
  const box = document.createElement('input');
  box.type = 'checkbox';
  box.checked = group.visible;
  box.onchange = () => { group.visible = box.checked; };
  const label = document.createElement('label');
  label.append(box, ' ' + name);
  controlsEl.append(label);
}

show(0);
// Look at the stones and their targets.
const focus = new THREE.Box3();
for (const g of scene.grasps) focus.expandByPoint(new THREE.Vector3(g.target[0], g.target[1], g.tcp[2]));
for (const s of scene.snapshots) for (const t of s.truth) focus.expandByPoint(new THREE.Vector3(t[0], t[1], t[2]));
const centre = focus.isEmpty() ? new THREE.Vector3(0, 0, isFinite(zmin) ? zmin : 0) : focus.getCenter(new THREE.Vector3());
const span = focus.isEmpty() ? radius : Math.max(6, focus.getSize(new THREE.Vector3()).length());
camera.position.set(centre.x - 0.8 * span, centre.y - 0.8 * span, centre.z + 0.7 * span);
controls.target.copy(centre);
controls.update();

function frame() {
  controls.update();
  renderer.render(world, camera);
  requestAnimationFrame(frame);
}
renderer.render(world, camera);

// Self-check: share of the canvas that is not background after the first frame.
const gl = renderer.getContext();
const px = new Uint8Array(4 * width * height);
gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, px);
const [br, bgg, bb] = [(BACKGROUND >> 16) & 255, (BACKGROUND >> 8) & 255, BACKGROUND & 255];  // sRGB, as drawn
let drawn = 0;
for (let i = 0; i < px.length; i += 4)
  if (Math.abs(px[i] - br) + Math.abs(px[i + 1] - bgg) + Math.abs(px[i + 2] - bb) > 24) drawn++;
const share = drawn / (width * height);
document.body.dataset.viewer = share > 0.01 ? 'ok' : 'blank';
document.body.dataset.drawn = share.toFixed(4);
status.textContent = `viewer ${document.body.dataset.viewer}: ${(100 * share).toFixed(1)} % of the canvas drawn, ${scene.snapshots.length} instants, ${scene.grasps.length} grasps`;
requestAnimationFrame(frame);
