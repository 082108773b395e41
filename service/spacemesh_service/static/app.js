// The SpaceMesh page: generate (POST /generate/stream), inspect, repair
// (POST /repair/stream) and download meshes. Everything comes from this server:
// the options and formats from /static/config.json, three.js from /static/vendor.
import * as THREE from "three";
import { OrbitControls } from "three/addons/OrbitControls.js";

const $ = (id) => document.getElementById(id);
const HEADER = "x-spacemesh-";
const DEGREE_COLOURS = { 3: "#3b6fd8", 4: "#2e9d57", 5: "#e39a1c", 6: "#c8412f" };
const MANY_COLOUR = "#8e44ad";
const HIGHLIGHT = new THREE.Color("#ff7a00");
const BASE = new THREE.Color("#b8c2d6");

// ------------------------------------------------------------------ requests
let apiKey = ""; // kept only in this page's memory
$("api-key").addEventListener("input", (e) => { apiKey = e.target.value.trim(); });

function authHeaders() {
  return apiKey ? { Authorization: `Bearer ${apiKey}` } : {};
}

/** A readable message of a problem+json body (or of any failed response). */
function problemText(problem, status) {
  if (!problem || typeof problem !== "object") return `HTTP ${status}`;
  let text = `${problem.title || "Error"}${problem.status ? ` (${problem.status})` : ""}: ` +
    `${problem.detail || ""}`;
  if (problem.option) text += `\noption: ${problem.option}`;
  if (problem.retry_after) text += `\ntry again in ${problem.retry_after} s`;
  if (problem.seed !== undefined) text += `\nseed: ${problem.seed}`;
  return text;
}

class RequestError extends Error {}

async function failed(response) {
  let body = null;
  try { body = await response.json(); } catch { body = null; }
  return new RequestError(problemText(body, response.status));
}

async function post(path, form) {
  const response = await fetch(path, { method: "POST", body: form, headers: authHeaders() });
  if (!response.ok) throw await failed(response);
  return response;
}

/** POST to a streaming route; calls onProgress(event) and resolves with the result event. */
async function postStream(path, form, onProgress) {
  const response = await post(path, form);
  const reader = response.body.getReader();
  const decoder = new TextDecoder();
  let buffer = "";
  let result = null;
  for (;;) {
    const { value, done } = await reader.read();
    if (value) buffer += decoder.decode(value, { stream: true });
    let end;
    while ((end = buffer.indexOf("\n\n")) >= 0) {
      const block = buffer.slice(0, end);
      buffer = buffer.slice(end + 2);
      let name = null;
      const data = [];
      for (const line of block.split("\n")) {
        if (line.startsWith("event:")) name = line.slice(6).trim();
        else if (line.startsWith("data:")) data.push(line.slice(5).trim());
      }
      if (!name) continue; // a keep-alive comment
      const event = JSON.parse(data.join("\n"));
      if (name === "progress") onProgress(event);
      else if (name === "problem") throw new RequestError(problemText(event, event.status));
      else if (name === "result") result = event;
    }
    if (done) break;
  }
  if (!result) throw new RequestError("the stream ended without a result");
  return result;
}

function decodeBase64(text) {
  const raw = atob(text);
  const bytes = new Uint8Array(raw.length);
  for (let i = 0; i < raw.length; i++) bytes[i] = raw.charCodeAt(i);
  return bytes;
}

function saveBlob(blob, filename) {
  const a = document.createElement("a");
  a.href = URL.createObjectURL(blob);
  a.download = filename;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 10000);
}

function filenameOf(response, fallback) {
  const match = /filename="([^"]+)"/.exec(response.headers.get("content-disposition") || "");
  return match ? match[1] : fallback;
}

// ------------------------------------------------------------------ options (from config)
function optionInput(parameter, prefix) {
  const schema = parameter.schema || {};
  const id = `${prefix}-${parameter.name}`;
  const label = document.createElement("label");
  label.htmlFor = id;
  label.textContent = parameter.name;
  label.title = parameter.description || "";
  let input;
  if (schema.enum) {
    input = document.createElement("select");
    input.append(new Option("(default)", ""));
    for (const value of schema.enum) input.append(new Option(value, value));
  } else if (schema.type === "boolean") {
    input = document.createElement("select");
    for (const [text, value] of [["(default)", ""], ["true", "true"], ["false", "false"]]) {
      input.append(new Option(text, value));
    }
  } else {
    input = document.createElement("input");
    input.type = schema.type === "integer" || schema.type === "number" ? "number" : "text";
    if (schema.type === "integer") input.step = "1";
    if (schema.type === "number") input.step = "any";
    if (schema.minimum !== undefined) input.min = schema.minimum;
    if (schema.maximum !== undefined) input.max = schema.maximum;
    input.placeholder = "default";
  }
  input.id = id;
  input.name = parameter.name;
  input.title = parameter.description || "";
  return [label, input];
}

function buildOptions(form, parameters, prefix) {
  for (const parameter of parameters) {
    if (parameter.name === "format") continue; // the page reads JSON; downloads pick theirs
    form.append(...optionInput(parameter, prefix));
  }
}

function chosenOptions(form) {
  const options = {};
  for (const input of form.elements) {
    if (input.name && input.value !== "") options[input.name] = input.value;
  }
  return options;
}

// ------------------------------------------------------------------ viewer
class Viewer {
  constructor(element) {
    this.element = element;
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    element.appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color("#e9ecf2");
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.001, 1000);
    this.camera.position.set(2, 1.5, 2.5);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x445066, 1.6));
    const light = new THREE.DirectionalLight(0xffffff, 1.6);
    light.position.set(3, 5, 4);
    this.camera.add(light);
    this.scene.add(this.camera);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.addEventListener("change", () => this.render());
    this.group = new THREE.Group();
    this.scene.add(this.group);
    this.points = null;
    this.mesh = null;
    new ResizeObserver(() => this.resize()).observe(element);
    this.resize();
  }

  resize() {
    const { clientWidth: w, clientHeight: h } = this.element;
    if (!w || !h) return;
    this.renderer.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.render();
  }

  render() { this.renderer.render(this.scene, this.camera); }

  clear() {
    for (const child of [...this.group.children]) {
      this.group.remove(child);
      child.geometry?.dispose();
      child.material?.dispose();
    }
    this.points = null;
    this.mesh = null;
    this.render();
  }

  /** Frame a box of positions (flat [x, y, z, ...]). */
  frame(positions) {
    const box = new THREE.Box3();
    const v = new THREE.Vector3();
    for (let i = 0; i < positions.length; i += 3) box.expandByPoint(v.set(positions[i], positions[i + 1], positions[i + 2]));
    if (box.isEmpty()) return;
    const centre = box.getCenter(new THREE.Vector3());
    const size = box.getSize(new THREE.Vector3()).length() || 1;
    this.size = size;
    this.controls.target.copy(centre);
    this.camera.near = size / 1000;
    this.camera.far = size * 100;
    this.camera.position.copy(centre).add(new THREE.Vector3(0.6, 0.45, 0.8).multiplyScalar(size * 1.2));
    this.camera.updateProjectionMatrix();
    this.controls.update();
  }

  setPoints(flat, visible = true) {
    if (this.points) { this.group.remove(this.points); this.points.geometry.dispose(); }
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute("position", new THREE.Float32BufferAttribute(flat, 3));
    const size = (this.size || 1) / 250;
    this.points = new THREE.Points(geometry, new THREE.PointsMaterial({ color: "#1d2330", size }));
    this.points.visible = visible;
    this.group.add(this.points);
    this.render();
  }

  /** Show a polygon mesh. colours: per face (THREE.Color) or per vertex (array), or null. */
  setMesh(mesh, mode, { faceColours = null, vertexColours = null } = {}) {
    if (this.mesh) { this.group.remove(this.mesh); this.mesh.traverse((o) => { o.geometry?.dispose(); o.material?.dispose(); }); }
    const { vertices, faces } = mesh;
    const positions = [];
    const colours = [];
    const triangleFace = [];
    faces.forEach((face, f) => {
      for (let k = 1; k + 1 < face.length; k++) {
        for (const v of [face[0], face[k], face[k + 1]]) {
          positions.push(...vertices[v]);
          const c = vertexColours ? vertexColours[v] : faceColours ? faceColours[f] : BASE;
          colours.push(c.r, c.g, c.b);
        }
        triangleFace.push(f);
      }
    });
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute("position", new THREE.Float32BufferAttribute(positions, 3));
    geometry.setAttribute("color", new THREE.Float32BufferAttribute(colours, 3));
    geometry.computeVertexNormals();
    const group = new THREE.Group();
    const surface = new THREE.Mesh(geometry, new THREE.MeshStandardMaterial({
      vertexColors: true, flatShading: true, side: THREE.DoubleSide, roughness: 0.7,
      polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1,
      transparent: mode === "wireframe", opacity: mode === "wireframe" ? 0.15 : 1,
    }));
    surface.userData.triangleFace = triangleFace;
    group.add(surface);
    const edges = [];
    const seen = new Set();
    for (const face of faces) {
      for (let k = 0; k < face.length; k++) {
        const a = face[k], b = face[(k + 1) % face.length];
        const key = a < b ? `${a},${b}` : `${b},${a}`;
        if (seen.has(key)) continue;
        seen.add(key);
        edges.push(...vertices[a], ...vertices[b]);
      }
    }
    const lines = new THREE.BufferGeometry();
    lines.setAttribute("position", new THREE.Float32BufferAttribute(edges, 3));
    group.add(new THREE.LineSegments(lines, new THREE.LineBasicMaterial({
      color: mode === "wireframe" ? "#1d2330" : "#2b3040", transparent: true,
      opacity: mode === "wireframe" ? 1 : 0.35,
    })));
    this.mesh = group;
    this.surface = surface;
    this.group.add(group);
    this.render();
  }

  /** The face under a pointer event and the hit point, or null. */
  pick(event) {
    if (!this.surface) return null;
    const rect = this.renderer.domElement.getBoundingClientRect();
    const pointer = new THREE.Vector2(((event.clientX - rect.left) / rect.width) * 2 - 1,
      -((event.clientY - rect.top) / rect.height) * 2 + 1);
    const ray = new THREE.Raycaster();
    ray.setFromCamera(pointer, this.camera);
    const hit = ray.intersectObject(this.surface)[0];
    if (!hit) return null;
    return { face: this.surface.userData.triangleFace[hit.faceIndex], point: hit.point };
  }

  /** Follow another viewer's camera. */
  follow(other) {
    other.controls.addEventListener("change", () => {
      this.camera.position.copy(other.camera.position);
      this.camera.quaternion.copy(other.camera.quaternion);
      this.controls.target.copy(other.controls.target);
      this.render();
    });
  }
}

function degreeColour(degree) {
  return new THREE.Color(DEGREE_COLOURS[degree] || MANY_COLOUR);
}

/** Per-vertex colours by distance to the nearest input point (blue near, red far). */
function distanceColours(vertices, flatPoints) {
  const count = flatPoints.length / 3;
  const step = Math.max(1, Math.floor(count / 4000)); // a bounded subset of the input
  const distances = vertices.map(([x, y, z]) => {
    let best = Infinity;
    for (let i = 0; i < count; i += step) {
      const dx = flatPoints[3 * i] - x, dy = flatPoints[3 * i + 1] - y, dz = flatPoints[3 * i + 2] - z;
      best = Math.min(best, dx * dx + dy * dy + dz * dz);
    }
    return Math.sqrt(best);
  });
  const top = Math.max(...distances, 1e-12);
  return {
    top,
    colours: distances.map((d) => new THREE.Color().setHSL(0.66 * (1 - d / top), 0.8, 0.5)),
  };
}

// ------------------------------------------------------------------ shared UI bits
function showError(element, error) {
  element.hidden = !error;
  element.textContent = error ? (error instanceof RequestError ? error.message : `Error: ${error.message || error}`) : "";
}

function statsTable(table, headers) {
  table.replaceChildren();
  for (const [name, value] of Object.entries(headers)) {
    const key = name.toLowerCase();
    if (!key.startsWith(HEADER)) continue;
    const row = table.insertRow();
    row.insertCell().textContent = key.slice(HEADER.length);
    // long decimals shortened for reading (the downloads keep every digit)
    row.insertCell().textContent = /^-?\d+\.\d{5,}(e[-+]?\d+)?$/i.test(value) ? Number(value).toPrecision(4) : value;
  }
}

function progressOf(bar, label) {
  return (event) => {
    bar.value = event.fraction;
    label.textContent = event.total > 1 ? `${event.stage} ${event.done}/${event.total}` : event.stage;
  };
}

function dropZone(zone, input, onFile) {
  zone.addEventListener("dragover", (e) => { e.preventDefault(); zone.classList.add("over"); });
  zone.addEventListener("dragleave", () => zone.classList.remove("over"));
  zone.addEventListener("drop", (e) => {
    e.preventDefault();
    zone.classList.remove("over");
    if (e.dataTransfer.files.length) onFile(e.dataTransfer.files[0]);
  });
  input.addEventListener("change", () => { if (input.files.length) onFile(input.files[0]); });
}

async function preview(file, kind) {
  const form = new FormData();
  form.append("file", file, file.name);
  form.append("kind", kind);
  return (await post(config.routes.preview, form)).json();
}

// ------------------------------------------------------------------ generate
const generate = { file: null, points: null, mesh: null, result: null, options: null };
let config = null;
let viewer = null;

function showGenerated() {
  if (!generate.mesh) return;
  const mode = $("mode").value;
  const legend = $("legend");
  legend.replaceChildren();
  const colours = {};
  if (mode === "degree") {
    colours.faceColours = generate.mesh.faces.map((f) => degreeColour(f.length));
    for (const [degree, colour] of [...Object.entries(DEGREE_COLOURS), ["7+", MANY_COLOUR]]) {
      const span = document.createElement("span");
      span.style.background = colour;
      span.textContent = `${degree}-gon`;
      legend.append(span);
    }
  } else if (mode === "distance" && generate.points) {
    const { top, colours: vertexColours } = distanceColours(generate.mesh.vertices, generate.points);
    colours.vertexColours = vertexColours;
    legend.textContent = `blue 0 … red ${top.toPrecision(3)} (mesh units)`;
  }
  viewer.setMesh(generate.mesh, mode, colours);
}

async function loadGenerateFile(file) {
  generate.file = file;
  generate.mesh = generate.result = null;
  $("drop-text").textContent = file.name;
  $("run").disabled = false;
  $("downloads").replaceChildren();
  $("stats").replaceChildren();
  showError($("error"), null);
  viewer.clear();
  try {
    const body = await preview(file, "points");
    generate.points = body.points;
    viewer.frame(body.points);
    viewer.setPoints(body.points, $("show-points").checked);
  } catch (error) {
    generate.points = null;
    showError($("error"), error);
  }
}

function generateForm(options, format) {
  const form = new FormData();
  form.append("file", generate.file, generate.file.name);
  for (const [name, value] of Object.entries(options)) form.append(name, value);
  form.append("format", format);
  return form;
}

async function runGenerate() {
  showError($("error"), null);
  $("run").disabled = true;
  $("progress").value = 0;
  $("stage").textContent = "sending";
  document.body.dataset.generate = "running";
  try {
    const options = chosenOptions($("options"));
    const result = await postStream(config.routes.generate_stream, generateForm(options, "json"),
      progressOf($("progress"), $("stage")));
    const bytes = decodeBase64(result.body);
    generate.result = { ...result, bytes };
    generate.mesh = JSON.parse(new TextDecoder().decode(bytes));
    // the seed the server used (picked at random when none was given) replays the mesh;
    // with samples, the winner's seed alone gives the winner's mesh
    generate.options = { ...options, seed: String(generate.mesh.seed) };
    if (options.samples) generate.options.samples = "1";
    $("progress").value = 1;
    $("stage").textContent = "done";
    showGenerated();
    if (generate.points) viewer.setPoints(generate.points, $("show-points").checked);
    statsTable($("stats"), result.headers);
    downloadButtons($("downloads"), (format) => downloadGenerated(format));
    document.body.dataset.generate = "done";
  } catch (error) {
    showError($("error"), error);
    $("stage").textContent = "failed";
    document.body.dataset.generate = "failed";
  } finally {
    $("run").disabled = false;
  }
}

function downloadButtons(element, download) {
  element.replaceChildren();
  for (const format of config.output_formats) {
    const button = document.createElement("button");
    button.type = "button";
    button.textContent = `⤓ ${format}`;
    button.dataset.format = format;
    button.addEventListener("click", () => download(format));
    element.append(button);
  }
}

async function downloadGenerated(format) {
  const { result } = generate;
  try {
    if (format === result.format) {
      saveBlob(new Blob([result.bytes], { type: result.media_type }), result.filename);
      return;
    }
    // the same request with the seed it used, in another format: the same mesh
    const response = await post(config.routes.generate, generateForm(generate.options, format));
    saveBlob(await response.blob(), filenameOf(response, `spacemesh.${format}`));
  } catch (error) {
    showError($("error"), error);
  }
}

// ------------------------------------------------------------------ repair
const repair = { file: null, mesh: null, selected: new Set(), sphere: null, auto: null,
  result: null, options: null, region: null };
let before = null;
let after = null;

function faceKeys(mesh) {
  const keys = new Set();
  for (const face of mesh.faces) keys.add(face.map((v) => mesh.vertices[v].join(",")).sort().join(";"));
  return keys;
}

function currentRegion() {
  if (repair.auto) return { auto: repair.auto };
  if (repair.sphere) return { sphere: repair.sphere };
  if (repair.selected.size) return { faces: [...repair.selected].sort((a, b) => a - b) };
  return null;
}

function sphereFaces(center, radius) {
  const inside = new Set();
  repair.mesh.faces.forEach((face, f) => {
    if (face.some((v) => new THREE.Vector3(...repair.mesh.vertices[v]).distanceTo(center) <= radius)) inside.add(f);
  });
  return inside;
}

function showSelection() {
  const region = currentRegion();
  let highlighted = repair.selected;
  if (repair.sphere) highlighted = sphereFaces(new THREE.Vector3(...repair.sphere.center), repair.sphere.radius);
  const faceColours = repair.mesh.faces.map((_, f) => (highlighted.has(f) ? HIGHLIGHT : BASE));
  before.setMesh(repair.mesh, "shaded", { faceColours });
  const shown = JSON.stringify(region, (_, v) => (typeof v === "number" && !Number.isInteger(v) ? Number(v.toPrecision(4)) : v));
  $("selection").textContent = region ? `region: ${shown.length > 160 ? `${shown.slice(0, 157)}...` : shown}` : "no region selected";
  $("repair-run").disabled = !region;
}

async function loadRepairFile(file) {
  repair.file = file;
  repair.selected = new Set();
  repair.sphere = repair.auto = repair.result = null;
  $("repair-drop-text").textContent = file.name;
  $("repair-downloads").replaceChildren();
  $("repair-stats").replaceChildren();
  showError($("repair-error"), null);
  before.clear();
  after.clear();
  try {
    const body = await preview(file, "mesh");
    const vertices = [];
    for (let i = 0; i < body.vertices.length; i += 3) vertices.push(body.vertices.slice(i, i + 3));
    repair.mesh = { vertices, faces: body.faces };
    before.frame(body.vertices);
    after.frame(body.vertices);
    showSelection();
  } catch (error) {
    repair.mesh = null;
    showError($("repair-error"), error);
  }
}

function onPick(event) {
  if (!repair.mesh || event.button !== 0) return;
  const hit = before.pick(event);
  if (!hit) return;
  repair.auto = null;
  if (document.querySelector("input[name=tool]:checked").value === "sphere") {
    repair.selected = new Set();
    repair.sphere = { center: hit.point.toArray(), radius: Number($("radius").value) * (before.size || 1) };
  } else {
    repair.sphere = null;
    if (repair.selected.has(hit.face)) repair.selected.delete(hit.face);
    else repair.selected.add(hit.face);
  }
  showSelection();
}

function repairForm(options, format) {
  const form = new FormData();
  form.append("file", repair.file, repair.file.name);
  form.append("region", JSON.stringify(repair.region));
  for (const [name, value] of Object.entries(options)) form.append(name, value);
  form.append("format", format);
  return form;
}

async function runRepair() {
  showError($("repair-error"), null);
  $("repair-run").disabled = true;
  $("repair-progress").value = 0;
  document.body.dataset.repair = "running";
  try {
    const options = chosenOptions($("repair-options"));
    repair.region = currentRegion();
    const result = await postStream(config.routes.repair_stream, repairForm(options, "json"),
      progressOf($("repair-progress"), $("repair-stage")));
    const bytes = decodeBase64(result.body);
    const mesh = JSON.parse(new TextDecoder().decode(bytes));
    repair.result = { ...result, bytes, mesh };
    repair.options = { ...options, seed: String(mesh.seed) };
    const old = faceKeys(repair.mesh);
    const fresh = mesh.faces.map((face) => !old.has(face.map((v) => mesh.vertices[v].join(",")).sort().join(";")));
    after.setMesh(mesh, "shaded", { faceColours: fresh.map((f) => (f ? HIGHLIGHT : BASE)) });
    $("repair-progress").value = 1;
    $("repair-stage").textContent = `done: ${fresh.filter(Boolean).length} faces re-generated`;
    statsTable($("repair-stats"), result.headers);
    downloadButtons($("repair-downloads"), (format) => downloadRepaired(format));
    document.body.dataset.repair = "done";
  } catch (error) {
    showError($("repair-error"), error);
    document.body.dataset.repair = "failed";
  } finally {
    $("repair-run").disabled = !currentRegion();
  }
}

async function downloadRepaired(format) {
  const { result } = repair;
  try {
    if (format === result.format) {
      saveBlob(new Blob([result.bytes], { type: result.media_type }), result.filename);
      return;
    }
    const response = await post(config.routes.repair, repairForm(repair.options, format));
    saveBlob(await response.blob(), filenameOf(response, `spacemesh-repair.${format}`));
  } catch (error) {
    showError($("repair-error"), error);
  }
}

// ------------------------------------------------------------------ start
function showTab(name) {
  for (const tab of document.querySelectorAll(".tab")) tab.classList.toggle("active", tab.dataset.tab === name);
  $("generate").hidden = name !== "generate";
  $("repair").hidden = name !== "repair";
  for (const v of [viewer, before, after]) v?.resize();
}

async function start() {
  const response = await fetch("/static/config.json");
  config = await response.json();
  buildOptions($("options"), config.generate_options, "generate");
  buildOptions($("repair-options"), config.repair_options, "repair");
  $("file").accept = config.input_formats.points.map((f) => `.${f}`).join(",");
  $("repair-file").accept = config.input_formats.mesh.map((f) => `.${f}`).join(",");
  viewer = new Viewer($("viewer"));
  before = new Viewer($("before"));
  after = new Viewer($("after"));
  after.follow(before);
  before.follow(after);
  dropZone($("drop"), $("file"), loadGenerateFile);
  dropZone($("repair-drop"), $("repair-file"), loadRepairFile);
  $("run").addEventListener("click", runGenerate);
  $("repair-run").addEventListener("click", runRepair);
  $("mode").addEventListener("change", showGenerated);
  $("show-points").addEventListener("change", (e) => {
    if (viewer.points) { viewer.points.visible = e.target.checked; viewer.render(); }
  });
  for (const tab of document.querySelectorAll(".tab")) tab.addEventListener("click", () => showTab(tab.dataset.tab));
  let down = null;
  before.renderer.domElement.addEventListener("pointerdown", (e) => { down = [e.clientX, e.clientY]; });
  before.renderer.domElement.addEventListener("pointerup", (e) => {
    if (down && Math.hypot(e.clientX - down[0], e.clientY - down[1]) < 4) onPick(e); // a click, not a drag
  });
  for (const mode of config.auto_regions) {
    const button = document.createElement("button");
    button.type = "button";
    button.textContent = { holes: "fill holes", defects: "fix defects", all: "fix all" }[mode] || mode;
    button.dataset.auto = mode;
    button.addEventListener("click", () => {
      if (!repair.mesh) return;
      repair.auto = mode;
      repair.sphere = null;
      repair.selected = new Set();
      showSelection();
    });
    $("auto").append(button);
  }
  $("clear").addEventListener("click", () => {
    repair.selected = new Set();
    repair.sphere = repair.auto = null;
    if (repair.mesh) showSelection();
  });
  document.body.dataset.ready = "true";
}

start().catch((error) => {
  document.body.dataset.ready = "failed";
  showError($("error"), error);
});
