// fluidtex view: plays the mesh sequence of an output folder with three.js.
//
// The server (src/commands/view.rs) lists the frames at /api/frames and
// serves the folder's files at /files/NAME. Each frame is `mesh.F.glb`
// (texture embedded) or, when the run wrote no glb, `mesh.F.obj` with
// `color.F.png`. The patch view swaps the colour map for `patches.F.png`,
// which has the same atlas layout, so it needs no other UVs.
//
// URL parameters: frame=F (show frame F, paused), view=patches, play=0|1,
// fps=N. The element #status carries data-state="ready" once the frame asked
// for is drawn, for scripts that take screenshots.

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OBJLoader } from 'three/addons/loaders/OBJLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);

// fluidtex's preview camera (render/camera.rs): looks along this direction
// with +Y up and a 35 degree vertical field of view, so the page and
// preview.F.png show the liquid from the same side.
const VIEW_DIR = new THREE.Vector3(-0.45, -0.8, -0.4).normalize();
const FOV_Y = 35;
const CACHE_FRAMES = 24;

function setStatus(state, text) {
  const s = $('status');
  s.dataset.state = state;
  s.textContent = text;
  document.title = `fluidtex view: ${text}`;
}

const canvas = $('canvas');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.outputColorSpace = THREE.SRGBColorSpace;
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1e1e24);
scene.add(new THREE.HemisphereLight(0xffffff, 0x505058, 1.5));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
scene.add(sun);
scene.add(sun.target);
const camera = new THREE.PerspectiveCamera(FOV_Y, 1, 0.01, 100);
const controls = new OrbitControls(camera, canvas);
controls.addEventListener('change', () => draw());

const gltfLoader = new GLTFLoader();
const objLoader = new OBJLoader();
const textureLoader = new THREE.TextureLoader();

let frames = [];
let index = 0;
let mode = params.get('view') === 'patches' ? 'patches' : 'texture';
let playing = false;
let busy = false;
let current = null;
let lastStep = 0;
const cache = new Map(); // frame index -> Promise of a loaded frame

function draw() {
  renderer.render(scene, camera);
}

function resize() {
  const w = canvas.clientWidth;
  const h = canvas.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
  draw();
}
window.addEventListener('resize', resize);

async function loadTexture(name, flipY, nearest) {
  const t = await textureLoader.loadAsync(`/files/${name}`);
  t.colorSpace = THREE.SRGBColorSpace;
  t.flipY = flipY;
  if (nearest) {
    // Patch colours are labels: never blend two patches into a third colour.
    t.magFilter = THREE.NearestFilter;
    t.minFilter = THREE.NearestFilter;
    t.generateMipmaps = false;
  }
  return t;
}

// Loads frame i: its mesh, its patch view and its stats.
async function loadFrame(i) {
  const f = frames[i];
  const glb = f.mesh.endsWith('.glb');
  let object;
  if (glb) {
    object = (await gltfLoader.loadAsync(`/files/${f.mesh}`)).scene;
  } else {
    object = await objLoader.loadAsync(`/files/${f.mesh}`);
    const map = f.color ? await loadTexture(f.color, true, false) : null;
    object.traverse((o) => {
      if (o.isMesh) {
        o.material = new THREE.MeshStandardMaterial({ map, roughness: 1, metalness: 0 });
      }
    });
  }
  const meshes = [];
  object.traverse((o) => { if (o.isMesh) meshes.push(o); });
  const colour = meshes.map((m) => m.material.map);
  // glTF UVs start at the image's top row, OBJ UVs at its bottom row.
  const patches = f.patches ? await loadTexture(f.patches, !glb, true) : null;
  let stats = null;
  if (f.stats) {
    try {
      stats = await (await fetch(`/files/${f.stats}`)).json();
    } catch (e) {
      stats = { error: `${f.stats}: ${e.message || e}` };
    }
  }
  return { object, meshes, colour, patches, stats, box: new THREE.Box3().setFromObject(object) };
}

function getFrame(i) {
  if (!cache.has(i)) {
    const p = loadFrame(i);
    p.catch(() => cache.delete(i));
    cache.set(i, p);
    evict();
  }
  return cache.get(i);
}

// Keeps the CACHE_FRAMES frames nearest to the current one.
function evict() {
  if (cache.size <= CACHE_FRAMES) return;
  const far = [...cache.keys()].sort((a, b) => Math.abs(b - index) - Math.abs(a - index));
  for (const i of far.slice(0, cache.size - CACHE_FRAMES)) {
    const p = cache.get(i);
    cache.delete(i);
    p.then((e) => {
      if (current === e) return;
      e.object.traverse((o) => {
        if (o.isMesh) {
          o.geometry.dispose();
          o.material.dispose();
        }
      });
      e.colour.forEach((t) => t && t.dispose());
      if (e.patches) e.patches.dispose();
    }).catch(() => {});
  }
}

function applyMode() {
  if (!current) return;
  const patches = mode === 'patches' && current.patches;
  current.meshes.forEach((m, k) => {
    m.material.map = patches ? current.patches : current.colour[k];
    m.material.needsUpdate = true;
  });
  $('note').textContent = mode === 'patches' && !current.patches
    ? 'no patches.F.png for this frame (the run had --no-debug)' : '';
}

const escape = (s) => String(s).replace(/[&<>"]/g, (c) => `&#${c.charCodeAt(0)};`);

function showStats(stats, f) {
  const rows = [];
  const add = (key, v) => {
    if (v !== null && typeof v === 'object' && !Array.isArray(v)) {
      for (const [k, w] of Object.entries(v)) add(`${key}.${k}`, w);
      return;
    }
    let text = JSON.stringify(v);
    if (typeof v === 'number' && !Number.isInteger(v)) text = v.toPrecision(4);
    if (typeof v === 'string') text = v;
    rows.push(`<tr><td>${escape(key)}</td><td>${escape(text)}</td></tr>`);
  };
  if (stats) {
    for (const [k, v] of Object.entries(stats)) add(k, v);
  }
  $('title').textContent = `frame ${f.frame}`;
  $('stats').innerHTML = stats ? `<table>${rows.join('')}</table>` : '(no stats.F.json)';
}

// Places the camera so that every frame in `boxes` fits, as the preview does.
function frameCamera(boxes) {
  const box = new THREE.Box3();
  boxes.forEach((b) => box.union(b));
  if (box.isEmpty()) return;
  const sphere = box.getBoundingSphere(new THREE.Sphere());
  const r = Math.max(sphere.radius, 1e-6);
  const halfY = THREE.MathUtils.degToRad(FOV_Y / 2);
  const halfX = Math.atan(Math.tan(halfY) * camera.aspect);
  const dist = (r / Math.sin(Math.min(halfX, halfY))) * 1.05;
  camera.position.copy(sphere.center).addScaledVector(VIEW_DIR, -dist);
  camera.up.set(0, 1, 0);
  camera.near = Math.max(dist - 2 * r, dist * 0.01);
  camera.far = dist + 2 * r;
  camera.updateProjectionMatrix();
  controls.target.copy(sphere.center);
  controls.update();
  sun.position.copy(sphere.center).addScaledVector(new THREE.Vector3(0.3, 1, 0.6).normalize(), 4 * r);
  sun.target.position.copy(sphere.center);
}

async function show(i) {
  index = i;
  const f = frames[i];
  $('scrub').value = String(i);
  $('label').textContent = `frame ${f.frame} (${i + 1}/${frames.length})`;
  setStatus('loading', `loading frame ${f.frame}`);
  busy = true;
  let e;
  try {
    e = await getFrame(i);
  } catch (err) {
    busy = false;
    setStatus('error', `frame ${f.frame}: ${f.mesh}: ${err.message || err}`);
    return;
  }
  busy = false;
  if (index !== i) return; // a later request took over
  if (current) scene.remove(current.object);
  current = e;
  scene.add(e.object);
  applyMode();
  showStats(e.stats, f);
  draw();
  // Two animation frames: the frame is on screen, not only submitted.
  await new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)));
  if (index === i) setStatus('ready', `frame ${f.frame}`);
  if (i + 1 < frames.length) getFrame(i + 1).catch(() => {});
}

function setPlaying(p) {
  playing = p && frames.length > 1;
  $('play').innerHTML = playing ? '&#10074;&#10074;' : '&#9654;';
}

function tick(t) {
  requestAnimationFrame(tick);
  const fps = Math.min(Math.max(Number($('fps').value) || 24, 1), 120);
  if (playing && !busy && t - lastStep >= 1000 / fps) {
    lastStep = t;
    show((index + 1) % frames.length);
  }
}

async function main() {
  let list;
  try {
    list = await (await fetch('/api/frames')).json();
  } catch (err) {
    setStatus('error', `cannot list frames: ${err.message || err}`);
    return;
  }
  if (list.error || !list.frames || list.frames.length === 0) {
    setStatus('error', list.error || 'no frames in this folder');
    return;
  }
  frames = list.frames;
  document.title = `fluidtex view: ${list.dir}`;
  $('scrub').max = String(frames.length - 1);
  $('scrub').addEventListener('input', (ev) => { setPlaying(false); show(Number(ev.target.value)); });
  $('play').addEventListener('click', () => setPlaying(!playing));
  for (const r of document.querySelectorAll('input[name=mode]')) {
    r.checked = r.value === mode;
    r.addEventListener('change', () => { mode = r.value; applyMode(); draw(); });
  }
  if (params.get('fps')) $('fps').value = params.get('fps');
  window.addEventListener('keydown', (ev) => {
    if (ev.target.tagName === 'INPUT' && ev.target.type === 'number') return;
    if (ev.key === ' ') { setPlaying(!playing); ev.preventDefault(); }
    if (ev.key === 'ArrowRight') { setPlaying(false); show(Math.min(index + 1, frames.length - 1)); }
    if (ev.key === 'ArrowLeft') { setPlaying(false); show(Math.max(index - 1, 0)); }
    if (ev.key === 'p') {
      mode = mode === 'patches' ? 'texture' : 'patches';
      for (const r of document.querySelectorAll('input[name=mode]')) r.checked = r.value === mode;
      applyMode();
      draw();
    }
  });
  resize();
  // One camera for the whole sequence, from the first and last frames.
  try {
    const ends = await Promise.all([getFrame(0), getFrame(frames.length - 1)]);
    frameCamera(ends.map((e) => e.box));
  } catch (err) {
    setStatus('error', `${err.message || err}`);
    return;
  }
  const asked = params.get('frame');
  let start = 0;
  if (asked !== null) {
    start = frames.findIndex((f) => f.frame === Number(asked));
    if (start < 0) {
      setStatus('error', `no frame ${asked} in this folder`);
      return;
    }
  }
  setPlaying(params.get('play') === '1' || (asked === null && params.get('play') !== '0'));
  await show(start);
  requestAnimationFrame(tick);
}

main();
