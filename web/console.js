// The rangebayes operator's console: reads the WebSocket stream of the process that serves this page
// (console/protocol.h describes the binary messages) and sends commands to POST /api/control.
//
// Flow control (console/server.h): the page asks for credit flow and acknowledges each image once it is
// decoded and each mesh once it is drawn, so the server sends a topic's next message only then, always the
// newest one. A slow browser sees fewer frames, never older ones; a hidden tab acknowledges nothing and so
// receives no images or meshes until it is shown again.
import * as THREE from '/three/build/three.module.js';
import { OrbitControls } from '/three/examples/jsm/controls/OrbitControls.js';

const $ = (id) => document.getElementById(id);
// Text from the server (paths, error lines: a file name may hold any character) as HTML text, never markup.
const esc = (text) => String(text).replace(/&/g, '&amp;').replace(/</g, '&lt;').replace(/>/g, '&gt;')
  .replace(/"/g, '&quot;');
const state = {
  images: {left: 0, depth: 0, sigma: 0},
  meshes: 0,
  meshKind: 'smoothed',
  statusMessages: 0,
  lastStatus: null,
  latencies: [],
  toPage: [],
  captures: [],
  webgl: false,
  connected: false,
  instance: null,  // the server process's id (status.instance): another one means a restart, a new token
  reconnects: 0,
  depthSinceSigma: 0,  // depth maps received since the last σ map
  lastMeshMs: 0,
};
window.rbConsole = state;  // for tests and the benchmark

const hash = new URLSearchParams(location.hash.slice(1));
if (hash.get('token')) $('token').value = hash.get('token');
// Most updates per second the page asks for, per image and for the mesh (#images=N&meshes=N): an operator
// needs no more to follow the run, and a browser on the rig itself then leaves the cores to the pipeline.
const maxRate = { image: Number(hash.get('images')) || 10, mesh: Number(hash.get('meshes')) || 5 };

// --- 3D view -------------------------------------------------------------------------------------
const view = $('view3d');
let renderer = null, scene, camera, controls, meshObject = null, framed = false, renderPending = false;
let pendingMesh = null;  // the newest mesh received and not drawn yet
try {
  // No multisampling and per-vertex (Lambert) lighting: where WebGL runs in software (a headless browser on
  // the rig itself) the draw shares the pipeline's cores, and these cut its cost most (docs/journal/console.md).
  renderer = new THREE.WebGLRenderer({ antialias: false });
  state.webgl = true;
} catch (e) {
  view.textContent = 'no WebGL in this browser: the 3D view is off';
}
if (renderer) {
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setClearColor(0x14171b);
  view.appendChild(renderer.domElement);
  state.canvas = renderer.domElement;
  // Draws now, so that the canvas holds the picture until this task ends (for reading its pixels).
  state.drawNow = () => renderer.render(scene, camera);
  scene = new THREE.Scene();
  camera = new THREE.PerspectiveCamera(50, 1, 0.01, 1000);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x303040, 0.55));
  const head = new THREE.DirectionalLight(0xffffff, 0.75);
  camera.add(head);
  scene.add(camera);
  controls = new OrbitControls(camera, renderer.domElement);
  // Drawn only when something changed: an idle page costs the rig's CPU nothing.
  controls.addEventListener('change', () => requestRender());
  const resize = () => {
    const w = view.clientWidth, h = view.clientHeight;
    renderer.setSize(w, h, false);
    renderer.domElement.style.width = w + 'px';
    renderer.domElement.style.height = h + 'px';
    camera.aspect = w / Math.max(1, h);
    camera.updateProjectionMatrix();
    requestRender();
  };
  window.addEventListener('resize', resize);
  resize();
}
// One draw per animation frame at most; a mesh that came since the last one is built into the scene first.
function requestRender() {
  if (!renderer || renderPending) return;
  renderPending = true;
  requestAnimationFrame(() => {
    renderPending = false;
    const m = pendingMesh;
    pendingMesh = null;
    if (m) buildMesh(m);
    renderer.render(scene, camera);
    if (m) meshDrawn(m.header);
  });
}

function frameView(geometry) {
  geometry.computeBoundingSphere();
  const s = geometry.boundingSphere;
  // Start where the rig's left camera is, looking at the surface; the operator orbits from there.
  camera.position.set(0, 0, 0);
  camera.near = Math.max(1e-3, s.radius / 100);
  camera.far = (s.center.length() + s.radius) * 10 + 1;
  camera.updateProjectionMatrix();
  controls.target.copy(s.center);
  if (s.center.length() < 1e-9) camera.position.set(0, 0, s.radius * 3);
  controls.update();
}
$('reset-view').onclick = () => { if (meshObject) frameView(meshObject.geometry); };

function showMesh(header, positions, faces) {
  if (!renderer) { ack('mesh/' + header.kind); return; }
  if (pendingMesh) ack('mesh/' + pendingMesh.header.kind);  // replaced before it was drawn
  pendingMesh = { header, positions, faces };
  requestRender();
}

function buildMesh({ header, positions, faces }) {
  const p = new Float32Array(positions.length);
  // Camera frame (x right, y down, z forward) to three.js (y up, looking along -z).
  for (let i = 0; i < positions.length; i += 3) {
    p[i] = positions[i]; p[i + 1] = -positions[i + 1]; p[i + 2] = -positions[i + 2];
  }
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(p, 3));
  g.setIndex(new THREE.BufferAttribute(faces, 1));
  g.computeVertexNormals();
  if (!meshObject) {
    const material = new THREE.MeshLambertMaterial({ color: 0xb9c7d6, side: THREE.DoubleSide });
    meshObject = new THREE.Mesh(g, material);
    scene.add(meshObject);
  } else {
    meshObject.geometry.dispose();
    meshObject.geometry = g;
  }
  if (!framed) { frameView(g); framed = true; }
  $('mesh-info').textContent = `${header.kind}, frame ${header.frame}: ${header.faces} faces on the wire (${header.source_faces} in the pipeline)`;
}

// Capture to drawn: the frame's age when the server sent it plus the time since (one clock on loopback;
// a browser on another machine adds the offset between the two clocks).
function meshDrawn(header) {
  ack('mesh/' + header.kind);
  state.meshes++;
  const toPage = Date.now() - header.sent_unix_ms;
  const latency = header.age_ms + toPage;
  state.latencies.push(latency);
  state.toPage.push(toPage);  // the part after the server sent it
  if (state.latencies.length > 1000) { state.latencies.shift(); state.toPage.shift(); }
  const recent = state.latencies.slice(-20);
  $('latency').textContent = (recent.reduce((a, b) => a + b, 0) / recent.length).toFixed(0);
  state.lastMeshMs = Date.now();
}
// The latency is that of the last meshes: with none for a while (a stall, a pause, the end of the run) it is
// no longer the rig's, so it is blanked.
setInterval(() => {
  if (Date.now() - state.lastMeshMs > 3000) $('latency').textContent = '-';
}, 1000);

for (const b of document.querySelectorAll('#mesh-kinds button')) {
  b.onclick = () => selectKind(b.dataset.kind);
}
function selectKind(kind) {
  state.meshKind = kind;
  for (const b of document.querySelectorAll('#mesh-kinds button')) b.classList.toggle('on', b.dataset.kind === kind);
  if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify({ subscribe: { mesh: kind } }));
}

// --- stream --------------------------------------------------------------------------------------
// Acknowledgements wait while the tab is hidden (the server then sends nothing heavy to it) and keep to
// maxRate: a topic's next message is asked for no sooner than 1/maxRate s after the last one was.
const heldAcks = new Set();
const lastAckMs = {};
function ack(topic) {
  if (document.hidden) { heldAcks.add(topic); return; }
  const wait = lastAckMs[topic] + 1000 / maxRate[topic.split('/')[0]] - performance.now();
  if (wait > 0) { setTimeout(() => ack(topic), wait); return; }
  lastAckMs[topic] = performance.now();
  if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify({ ack: topic }));
}
document.addEventListener('visibilitychange', () => {
  if (document.hidden) return;
  const topics = [...heldAcks];
  heldAcks.clear();
  if (topics.length && ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify({ ack: topics }));
  if (state.lastStatus) onStatus(state.lastStatus);
});

const imageUrls = {};
function showImage(header, payload) {
  const el = $('img-' + header.kind);
  if (!el) { ack('image/' + header.kind); return; }
  const url = URL.createObjectURL(new Blob([payload], { type: header.format === 'png' ? 'image/png' : 'image/jpeg' }));
  if (imageUrls[header.kind]) URL.revokeObjectURL(imageUrls[header.kind]);
  imageUrls[header.kind] = url;
  el.src = url;
  if (header.kind === 'sigma') sigmaShown();
  el.decode().catch(() => {}).then(() => ack('image/' + header.kind));
  state.images[header.kind] = (state.images[header.kind] || 0) + 1;
  if (header.kind === 'depth') { $('depth-near').textContent = header.min.toFixed(2) + ' m'; $('depth-far').textContent = header.max.toFixed(2) + ' m'; }
  if (header.kind === 'sigma') { $('sigma-lo').textContent = (header.min * 1000).toFixed(1) + ' mm'; $('sigma-hi').textContent = (header.max * 1000).toFixed(1) + ' mm'; }
  $('frame').textContent = header.frame;
  // σ maps come only from the space-time matcher: when depth maps keep coming without one (SGBM chosen again),
  // the last σ map is no longer the run's and is taken away.
  if (header.kind === 'sigma') state.depthSinceSigma = 0;
  if (header.kind === 'depth') state.depthSinceSigma++;
  if (state.depthSinceSigma > 3) clearSigma();
}
function clearSigma() {
  const img = $('img-sigma');
  if (img.getAttribute('src')) img.removeAttribute('src');
  if (imageUrls.sigma) {
    URL.revokeObjectURL(imageUrls.sigma);
    delete imageUrls.sigma;
  }
  $('sigma-lo').textContent = '-';
  $('sigma-hi').textContent = '-';
  $('sigma-note').textContent = '- none from this matcher (SGBM): choose space-time';
}
function sigmaShown() {
  $('sigma-note').textContent = '';
}

function onBinary(buf) {
  if (buf.byteLength < 8) throw new Error('binary message of ' + buf.byteLength + ' bytes');
  const dv = new DataView(buf);
  const type = dv.getUint8(0);
  const n = dv.getUint32(4, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 8, n)));
  const start = Math.ceil((8 + n) / 4) * 4;
  if (type === 1) {
    showImage(header, buf.slice(start));
  } else if (type === 2) {
    const nv = dv.getUint32(start, true), nf = dv.getUint32(start + 4, true);
    const positions = new Float32Array(buf, start + 8, nv * 3);
    const faces = new Uint32Array(buf, start + 8 + 12 * nv, nf * 3);
    showMesh(header, positions, faces);
  }
}

const fmtBytes = (b) => b < 0 ? '?' : b > 1e9 ? (b / 1e9).toFixed(1) + ' GB' : (b / 1e6).toFixed(0) + ' MB';
// Settings fields the operator has changed and not yet sent: status updates leave them as the operator set them.
const settingFields = ['budget', 'ds', 'matcher', 'window'];
const dirty = new Set();
for (const id of settingFields) {
  const mark = () => {
    dirty.add(id);
    $(id).classList.add('dirty');
  };
  $(id).addEventListener('input', mark);
  $(id).addEventListener('change', mark);
}
function clean(ids) {
  for (const id of ids) {
    dirty.delete(id);
    $(id).classList.remove('dirty');
  }
}
state.dirty = dirty;
function showSetting(id, value) {
  if (dirty.has(id) || document.activeElement === $(id)) return;
  $(id).value = value;
}

// A new process on the same address (restarted): its captures, token and run are not the old ones.
function onNewInstance(s) {
  const restarted = state.instance !== null;
  state.instance = s.instance;
  if (!restarted) return;
  state.captures = [];
  $('captures').innerHTML = '';
  state.latencies.length = 0;
  state.toPage.length = 0;
  $('latency').textContent = '-';
  state.depthSinceSigma = 0;
  framed = false;
  state.restarted = true;
  showBanner(
      'the rig process restarted (new run, started ' + new Date(s.started_unix_ms).toLocaleTimeString() +
          '): its controls need the new token it printed',
      'bad');
}

function onStatus(s) {
  state.statusMessages++;
  state.lastStatus = s;
  if (s.instance !== undefined && s.instance !== state.instance) onNewInstance(s);
  if (document.hidden) return;  // drawn when the tab is shown again
  $('fps').textContent = s.fps.toFixed(1);
  const run = $('run');
  run.textContent = s.settings.paused ? 'paused' : s.running ? 'running' : s.finished ? 'finished' : 'waiting';
  run.className = 'pill ' + (s.settings.paused ? 'warn' : s.running ? 'ok' : '');
  const c = s.console;
  $('counters').innerHTML =
      [
        ['frames in', s.frames_in],
        ['results', s.results],
        ['dropped', s.dropped],
        ['failed', s.failed],
        ['skipped', s.skipped],
        ['camera timeouts', s.timeouts],
        ['to pages: dropped', c.messages_dropped],
        ['to pages: replaced by newer', c.messages_coalesced],
        ['console skipped', c.results_skipped],
      ].map(([k, v]) => `<tr><td>${k}</td><td>${v}</td></tr>`)
          .join('');
  $('stages').querySelector('tbody').innerHTML = s.stages.map((t) =>
    `<tr><td>${t.name}</td><td>${t.mean_ms.toFixed(1)}</td><td>${t.items}</td><td>${t.errors}</td></tr>`).join('');
  // Queue i lies between stage i and stage i + 1.
  const stageName = (i) => (s.stages[i] ? esc(s.stages[i].name) : '?');
  $('queues').innerHTML =
      s.queue_fill
          .map(
              (f, i) => `<div class="queue">${stageName(i)}&rarr;${stageName(i + 1)} <div class="fill" style="width:${
                  Math.round(60 * f / Math.max(1, s.queue_capacity))}px"></div> ${f}/${s.queue_capacity}</div>`)
          .join('');
  const r = s.recording;
  $('recording').innerHTML = r.active
    ? `<b>recording</b> into ${esc(r.folder)}: ${r.frames_written} frames written, ${r.frames_dropped} dropped${r.error ? ', error: ' + esc(r.error) : ''}; disk left ${fmtBytes(r.disk_free_bytes)}`
    : `not recording${r.last && r.last.name ? ` (last: ${esc(r.last.folder)}, ${r.last.frames_written} frames)` : ''}; disk left ${fmtBytes(r.disk_free_bytes)}`;
  $('errors').innerHTML = s.errors.map((e) => `<li>${esc(e)}</li>`).join('');
  showSetting('budget', s.settings.smooth_budget_ms);
  showSetting('ds', String(s.settings.stereo_downsample));
  showSetting('matcher', s.settings.matcher);
  showSetting('window', s.settings.window_frames);
  for (const b of document.querySelectorAll('#mesh-kinds button')) {
    b.disabled = !s.mesh_kinds.includes(b.dataset.kind);
    b.title = b.disabled ?
        (b.dataset.kind === 'decimated' ? 'no decimated mesh in this run (decimation off: --decimate)' :
                                          'no such mesh in this run') :
        '';
  }
  const controls = s.controls !== false;
  $('controls').hidden = !controls;
  $('no-controls').hidden = controls;
  const over = s.finished ? 'the run has finished' : '';
  for (const id of ['pause', 'resume', 'capture', 'rec-start', 'budget-set', 'budget-none', 'ds-set', 'matcher-set']) {
    $(id).disabled = !!over;
    $(id).title = over;
  }
  $('pause').disabled = !!over || s.settings.paused;
  $('resume').disabled = !!over || !s.settings.paused;
  $('rec-start').disabled = !!over || s.recording.active;
  $('rec-stop').disabled = !s.recording.active;
  const cs = $('capture-state');
  if (s.capture_pending) {
    cs.className = 'pending';
    cs.textContent = s.settings.paused ? 'capture pending: resume the run to take the frame' :
                                         'capturing a full-quality frame… (the live view goes on meanwhile)';
  } else if (s.capture_error) {
    cs.className = 'err';
    cs.textContent = 'capture failed: ' + s.capture_error + ' - try again';
  } else {
    cs.className = '';
    cs.textContent = '';
  }
  if (s.mesh_kinds.length && !s.mesh_kinds.includes(state.meshKind)) selectKind(s.mesh_kinds[s.mesh_kinds.length > 1 ? 1 : 0]);
  for (const cap of s.captures) addCapture(cap);
}

state.showStatus = onStatus;  // for the test that feeds it text with markup in it

function addCapture(cap) {
  if (state.captures.includes(cap.id)) return;
  state.captures.push(cap.id);
  const li = document.createElement('li');
  li.innerHTML = `<a href="${esc(cap.url)}" download>capture ${cap.id}</a> (frame ${cap.frame}, ${cap.faces} faces, PLY)`;
  $('captures').appendChild(li);
}

function showBanner(text, kind) {
  const b = $('banner');
  b.hidden = !text;
  b.textContent = text || '';
  b.className = kind || '';
}

let ws = null;
let retryS = 1;  // the wait before the next attempt: 1, 2, 4, 8, then 10 s
let lastDataMs = 0;
let retryTimer = null;
function connect() {
  retryTimer = null;
  ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => {
    state.connected = true;
    retryS = 1;
    document.body.classList.remove('disconnected');
    if (!state.restarted) showBanner('');
    $('conn').textContent = 'connected';
    $('conn').className = 'pill ok';
    ws.send(JSON.stringify({ subscribe: { mesh: state.meshKind }, flow: 'credit' }));
  };
  ws.onmessage = (ev) => {
    lastDataMs = Date.now();
    // A message the page cannot read is counted and shown, and the stream goes on.
    try {
      if (typeof ev.data === 'string') {
        const m = JSON.parse(ev.data);
        if (m.type === 'status')
          onStatus(m);
        else if (m.type === 'capture')
          addCapture(m);
      } else {
        onBinary(ev.data);
      }
    } catch (e) {
      state.badMessages = (state.badMessages || 0) + 1;
      console.warn('unreadable message from the rig process:', e);
    }
  };
  ws.onclose = () => {
    const was = state.connected;
    state.connected = false;
    heldAcks.clear();
    pendingMesh = null;
    if (was) state.reconnects++;
    // What the page shows is now only the last it heard: marked so, and the run's state is unknown.
    document.body.classList.add('disconnected');
    $('conn').textContent = 'disconnected';
    $('conn').className = 'pill bad';
    $('run').textContent = 'state unknown';
    $('run').className = 'pill';
    $('fps').textContent = '-';
    $('latency').textContent = '-';
    const seen = lastDataMs ? ` (last data ${new Date(lastDataMs).toLocaleTimeString()})` : '';
    showBanner(`lost connection to the rig process${seen}: retrying in ${retryS} s`, 'bad');
    retryTimer = setTimeout(connect, retryS * 1000);
    retryS = Math.min(10, retryS * 2);
  };
}
connect();

// --- controls ------------------------------------------------------------------------------------
// The feedback line sits under the header, so that it is seen without scrolling.
function feedback(text, ok) {
  const fb = $('feedback');
  fb.className = ok ? '' : 'err';
  fb.textContent = text;
}
async function control(body) {
  let r;
  try {
    r = await fetch('/api/control', {
      method: 'POST',
      headers: {'Content-Type': 'application/json', 'X-Rangebayes-Token': $('token').value.trim()},
      body: JSON.stringify(body),
    });
  } catch (e) {
    feedback(`${body.cmd}: not sent: no connection to the rig process (${e.message || e})`, false);
    return {status: 0, body: {error: String(e)}};
  }
  let answer = null;
  try {
    answer = await r.json();
  } catch (e) {
    feedback(`${body.cmd}: the rig process answered ${r.status} without a readable reply`, false);
    return {status: r.status, body: {error: 'unreadable reply'}};
  }
  if (r.status === 200) {
    if (state.restarted) {
      state.restarted = false;
      showBanner('');
    }
    feedback(`${body.cmd}: ok${answer.folder ? ' (' + answer.folder + ')' : ''}`, true);
  } else {
    const hint =
        r.status === 403 && state.restarted ? ' - the rig process restarted: enter the token it printed now' : '';
    feedback(`${body.cmd}: refused (${r.status}): ${answer.error}${hint}`, false);
  }
  return {status: r.status, body: answer};
}
state.control = control;
// Sends a "set" for the given fields; they keep the operator's value (dirty) until it is accepted.
async function set(fields, values) {
  const reply = await control(Object.assign({cmd: 'set'}, values));
  if (reply.status === 200) clean(fields);
  return reply;
}
$('pause').onclick = () => control({ cmd: 'pause' });
$('resume').onclick = () => control({ cmd: 'resume' });
$('capture').onclick = () => control({ cmd: 'capture_now' });
$('rec-start').onclick = () => control({ cmd: 'record_start', name: $('rec-name').value.trim() });
$('rec-stop').onclick = () => control({ cmd: 'record_stop' });
$('budget-set').onclick = () => {
  const text = $('budget').value.trim();
  const ms = Number(text);
  if (text === '' || !Number.isFinite(ms) || ms < 0) {
    feedback('set: not sent: the smoothing budget must be a number of ms ≥ 0 (0 or "no budget": none)', false);
    return;
  }
  set(['budget'], {smooth_budget_ms: ms});
};
$('budget-none').onclick = () => {
  $('budget').value = 0;
  set(['budget'], {smooth_budget_ms: 0});
};
$('ds-set').onclick = () => set(['ds'], {stereo_downsample: Number($('ds').value)});
$('matcher-set').onclick = () => {
  const w = Number($('window').value);
  if (!Number.isInteger(w) || w < 1 || w > 256) {
    feedback('set: not sent: the window must be a whole number of frames from 1 to 256', false);
    return;
  }
  set(['matcher', 'window'], {matcher: $('matcher').value, window_frames: w});
};
