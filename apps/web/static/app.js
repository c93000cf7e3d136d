// The dancesynth page: three tabs over the JSON API of apps/web/server.py. No framework, no external asset.
"use strict";

const $ = (sel, root = document) => root.querySelector(sel);
const state = { config: null, uploads: {}, cards: {}, models: [] };
const POLL_MS = 1000;

function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "text") node.textContent = v;
    else if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else node.setAttribute(k, v);
  }
  for (const c of children) node.append(c);
  return node;
}

async function api(path, options = {}) {
  const response = await fetch(path, options);
  let body = null;
  try { body = await response.json(); } catch (e) { /* an empty or non-JSON answer */ }
  if (!response.ok) throw new Error((body && body.error) || `The server answered ${response.status}; try again.`);
  return body;
}

const post = (path, body) => api(path, { method: "POST", headers: { "Content-Type": "application/json" },
                                         body: JSON.stringify(body) });

function duration(seconds) {
  seconds = Math.round(seconds);
  if (seconds >= 3600) return `${Math.floor(seconds / 3600)} h ${Math.floor(seconds % 3600 / 60)} min`;
  if (seconds >= 60) return `${Math.floor(seconds / 60)} min ${seconds % 60} s`;
  return `${seconds} s`;
}

// --- tabs -------------------------------------------------------------------------------------------------
function showTab(name) {
  for (const b of document.querySelectorAll("nav button")) b.setAttribute("aria-selected", b.dataset.tab === name);
  for (const s of document.querySelectorAll("section.tab")) s.hidden = s.id !== `tab-${name}`;
  history.replaceState(null, "", `#${name}`);
}

// --- uploads ----------------------------------------------------------------------------------------------
// Uploads at once when a file is chosen; the server checks it (a song it can decode, a video long enough).
function uploader(input, kind, status, onDone) {
  input.addEventListener("change", () => {
    const file = input.files[0];
    delete state.uploads[input.id];
    status.className = "status";
    if (!file) { status.textContent = ""; return; }
    const limit = state.config.max_upload_mb;
    if (file.size > limit * 1048576) {
      showError(status, `${file.name} is ${Math.round(file.size / 1048576)} MB, over this server's upload limit ` +
                `of ${limit} MB; use a shorter file or start the server with a larger --max-upload-mb.`);
      return;
    }
    const form = new FormData();
    form.append("kind", kind);
    form.append("file", file);
    const xhr = new XMLHttpRequest();
    xhr.open("POST", "/api/uploads");
    xhr.setRequestHeader("X-File-Name", file.name.replace(/[^\x20-\x7e]/g, "_"));
    xhr.upload.onprogress = e => { status.textContent = `uploading ${file.name}: ${Math.round(100 * e.loaded / e.total)}%`; };
    xhr.onload = () => {
      let body = {};
      try { body = JSON.parse(xhr.responseText); } catch (e) { /* not JSON */ }
      if (xhr.status !== 200) { showError(status, body.error || `Upload failed (${xhr.status}); try again.`); return; }
      state.uploads[input.id] = body;
      status.className = "status ok";
      status.textContent = `✓ ${body.name}, ${duration(body.duration)}`;
      if (onDone) onDone(body);
    };
    xhr.onerror = () => showError(status, `The upload of ${file.name} failed; check the server is running and try again.`);
    status.textContent = `uploading ${file.name}…`;
    xhr.send(form);
  });
}

function showError(node, message) {
  node.className = "status error";
  node.textContent = message;
}

// --- lists ------------------------------------------------------------------------------------------------
async function loadSongs() {
  const select = $("#builtin-song");
  const songs = await api("/api/songs");
  select.replaceChildren(...songs.map(s => el("option", { value: s.id, text: s.name })));
}

async function loadPoseModels() {
  const select = $("#pose-model");
  const chosen = select.value;
  const runs = await api("/api/pose-models");
  select.replaceChildren(...runs.map(r => el("option", { value: r.id, text: r.name })));
  if (runs.some(r => r.id === chosen)) select.value = chosen;
}

async function loadModels() {
  const listed = await api("/api/models");
  // A damaged entry is listed with the sentence saying why, and offered for nothing.
  const models = listed.filter(m => !m.damaged);
  state.models = models;
  const select = $("#dance-model");
  const chosen = select.value;
  select.replaceChildren(...models.map(m => el("option", { value: m.name,
    text: `${m.video} · ${m.preset} · SSIM ${m.ssim == null ? "?" : m.ssim.toFixed(3)} · ${duration(m.trained_seconds)}` })));
  if (!models.length) select.append(el("option", { value: "", text: "(none yet: train one, or use a video)" }));
  if (models.some(m => m.name === chosen)) select.value = chosen;
  $("#models-table tbody").replaceChildren(...listed.map(m => m.damaged
    ? el("tr", { "data-model": m.name }, el("td", { text: m.name }), el("td", { colspan: 6, class: "error", text: m.damaged }))
    : el("tr", { "data-model": m.name },
      el("td", { text: m.video, title: m.name }), el("td", { text: m.preset }), el("td", { text: m.size.join("×") }),
      el("td", { class: "ssim", text: m.ssim == null ? "–" : m.ssim.toFixed(3) }),
      el("td", { text: duration(m.trained_seconds) + (m.finished ? " (all epochs)" : "") }),
      el("td", { text: m.step }),
      el("td", {}, el("button", { type: "button", text: "Continue", onclick: () => train({ model: m.name }, $("#train-error")) })))));
  if (!listed.length) $("#models-table tbody").append(el("tr", {}, el("td", { colspan: 7, class: "empty",
    text: "No appearance model in the cache yet." })));
}

// --- starting jobs ----------------------------------------------------------------------------------------
async function startJob(body, errorNode, button) {
  errorNode.textContent = "";
  if (button) button.disabled = true;
  try {
    const job = await post("/api/jobs", body);
    await refreshJobs();
    const card = state.cards[job.id];
    if (card) card.node.scrollIntoView({ block: "nearest" });
    return job;
  } catch (e) {
    errorNode.textContent = e.message;
  } finally {
    if (button) button.disabled = false;
  }
}

function uploaded(inputId, what) {
  const upload = state.uploads[inputId];
  if (!upload) throw new Error(`Choose ${what} first and wait for its upload to finish.`);
  return upload.id;
}

function dance(event) {
  event.preventDefault();
  const error = $("#dance-error");
  const body = { kind: "dance", start: $("#start").value, duration: $("#duration").value || null, seed: $("#seed").value,
                 pose_model: $("#pose-model").value };
  try {
    body.song = document.querySelector("input[name=song-source]:checked").value === "upload"
      ? uploaded("song-file", "a song file") : $("#builtin-song").value;
    if (document.querySelector("input[name=target-source]:checked").value === "model") {
      body.model = $("#dance-model").value;
      if (!body.model) throw new Error("There is no trained appearance model yet: choose a video of the person instead.");
    } else {
      body.video = uploaded("dance-video", "a video of the person");
      body.minutes = $("#dance-minutes").value;
    }
  } catch (e) { error.textContent = e.message; return; }
  startJob(body, error, $("#dance-button"));
}

function train(target, error) {
  startJob({ kind: "train", minutes: $("#train-minutes").value, preset: $("#train-preset").value, ...target }, error);
}

// --- job cards --------------------------------------------------------------------------------------------
const fileUrl = (job, name, download) => `/api/jobs/${job.id}/files/${name}${download ? "?download=1" : ""}`;

function progressText(job) {
  if (job.state === "queued") return job.position === 1 ? "waiting: next in the queue"
    : `waiting: position ${job.position} in the queue`;
  const p = job.progress;
  if (job.state === "running") {
    if (!p) return "starting…";
    if (p.took) return job.last_line || p.line;  // that step has finished; the next one has no progress line yet
    return `${p.what}: ${p.done}/${p.total} ${p.unit} (${p.percent}%)` + (p.left ? `, ${p.left} left` : "");
  }
  if (job.state === "done") return `finished in ${duration(job.finished - job.started)}`;
  return job.state;
}

function card(job) {
  const node = el("article", { class: `job ${job.state}`, "data-job": job.id, "data-kind": job.kind },
    el("header", {}, el("strong", { text: job.title }), el("span", { class: "state" }),
      el("button", { type: "button", class: "cancel", text: "Cancel", onclick: () => post(`/api/jobs/${job.id}/cancel`).then(refreshJobs) })),
    el("progress", { max: 100 }), el("p", { class: "progress-text" }), el("p", { class: "line" }),
    el("p", { class: "error", role: "alert" }), el("ul", { class: "warnings", role: "status" }), el("div", { class: "live" }),
    el("div", { class: "outputs" }));
  if (job.command) node.append(el("details", job.kind === "dance" ? { open: "" } : {}, el("summary", { text: "Equivalent command" }),
    el("code", { class: "command", text: job.command })));
  return { node, rendered: null, liveAt: 0 };
}

function updateCard(c, job) {
  const n = c.node;
  n.className = `job ${job.state}`;
  $(".state", n).textContent = job.state;
  $(".cancel", n).hidden = !["queued", "running"].includes(job.state);
  const bar = $("progress", n);
  bar.hidden = job.state !== "running";
  if (job.progress && job.state === "running") bar.value = job.progress.percent; else bar.removeAttribute("value");
  $(".progress-text", n).textContent = progressText(job);
  const line = job.state === "running" && job.last_line !== job.progress?.line ? job.last_line : "";
  $(".line", n).textContent = line || "";
  $(".error", n).textContent = job.error || "";
  const warnings = $(".warnings", n);
  if (warnings.childElementCount !== (job.warnings || []).length)
    warnings.replaceChildren(...(job.warnings || []).map(text => el("li", { text })));
  if (job.kind === "train" && Date.now() - c.liveAt > 3000 && job.state !== "queued") {
    c.liveAt = Date.now();
    if (job.state === "running" || !c.rendered) showTraining(c, job);
  }
  if (c.rendered !== job.state) {
    c.rendered = job.state;
    if (job.state === "done") showOutputs(c, job);
  }
}

function video(job, name, caption, wide = false) {
  return el("figure", wide ? { class: "wide" } : {}, el("video", { src: fileUrl(job, name), controls: "", preload: "auto", "data-output": name }),
    el("figcaption", { text: caption }));
}

function showOutputs(c, job) {
  const out = $(".outputs", c.node);
  if (job.kind === "dance") {
    out.replaceChildren(el("div", { class: "videos" }, video(job, "dance", "the dance"),
      video(job, "side_by_side", "skeleton | person", true), video(job, "skeleton", "skeleton")),
      el("a", { href: fileUrl(job, "dance", true), download: "dance.mp4", class: "download", text: "Download the dance (mp4)" }));
    if (job.params.target) loadModels();  // its video's appearance model trained into the cache
  } else if (job.kind === "preview") {
    out.replaceChildren(el("div", { class: "videos" }, el("figure", {}, el("img", { src: fileUrl(job, "image"), alt: "tracked skeleton" }),
      el("figcaption", { text: `person found in ${Math.round(100 * job.info.found)}% of the first frames` })),
      video(job, "preview", "the first seconds with the tracked skeleton")));
  } else if (job.kind === "demo") {
    // Its videos first, then its summary (metrics, frames, links): what `dancesynth demo` leaves in its folder.
    const videos = [["dance.mp4", "the dance"], ["side_by_side.mp4", "skeleton | person"], ["skeleton.mp4", "skeleton"]]
      .filter(([name]) => name in job.outputs).map(([name, caption]) => video(job, name, caption, name === "side_by_side.mp4"));
    const summary = el("div", { class: "markdown" });
    out.replaceChildren(el("div", { class: "videos" }, ...videos), summary);
    if ("dance.mp4" in job.outputs) summary.before(el("a", { href: fileUrl(job, "dance.mp4", true), download: "dance.mp4",
      class: "download", text: "Download the dance (mp4)" }));
    fetch(fileUrl(job, "summary.md")).then(r => r.text()).then(text => {
      summary.innerHTML = markdown(text, name => (name in job.outputs ? fileUrl(job, name) : name));
    });
  } else if (job.kind === "train") {
    loadModels();
  }
}

// The live loss plot (from the model's losses.csv) and its latest sample image: real | skeleton | generated.
async function showTraining(c, job) {
  const live = $(".live", c.node);
  const name = job.params.entry;
  let losses;
  try { losses = await api(`/api/models/${name}/losses`); } catch (e) { return; }
  const img = el("img", { src: `/api/models/${name}/sample?t=${Date.now()}`, alt: "latest held-out sample" });
  img.onerror = () => img.remove();
  live.replaceChildren(plot(losses), el("figure", {}, img, el("figcaption", { text: "held-out frames: real | skeleton | generated" })));
}

function plot(losses, width = 420, height = 220) {
  const svg = document.createElementNS("http://www.w3.org/2000/svg", "svg");
  svg.setAttribute("class", "plot");
  svg.setAttribute("width", width);
  svg.setAttribute("height", height);
  const names = Object.keys(losses.series);
  const colours = ["#6b3fa0", "#e07b00", "#1b7f3b", "#b00020", "#0060b0", "#777"];
  const all = names.flatMap(k => losses.series[k]).filter(v => v > 0);
  const add = (tag, attrs, text) => {
    const n = document.createElementNS("http://www.w3.org/2000/svg", tag);
    for (const [k, v] of Object.entries(attrs)) n.setAttribute(k, v);
    if (text) n.textContent = text;
    svg.append(n);
  };
  add("text", { x: 8, y: 16, "font-size": 12 }, `losses (log scale), step ${losses.step.at(-1) ?? 0}`);
  if (losses.step.length < 2 || !all.length) return svg;
  const lo = Math.log10(Math.min(...all)), hi = Math.log10(Math.max(...all)) + 1e-9;
  const s0 = losses.step[0], s1 = losses.step.at(-1);
  const x = s => 40 + (width - 50) * (s - s0) / Math.max(1, s1 - s0);
  const y = v => height - 20 - (height - 50) * (Math.log10(Math.max(v, 10 ** lo)) - lo) / (hi - lo);
  names.forEach((k, i) => {
    const points = losses.series[k].map((v, j) => `${x(losses.step[j]).toFixed(1)},${y(v).toFixed(1)}`).join(" ");
    add("polyline", { points, fill: "none", stroke: colours[i % colours.length], "stroke-width": 1.2 });
    add("text", { x: 40 + 70 * i, y: 32, "font-size": 11, fill: colours[i % colours.length] }, k);
  });
  add("text", { x: 2, y: 46, "font-size": 10 }, (10 ** hi).toPrecision(2));
  add("text", { x: 2, y: height - 20, "font-size": 10 }, (10 ** lo).toPrecision(2));
  return svg;
}

// Enough Markdown for the demo's summary.md: headings, tables, images, links, inline code, paragraphs.
function markdown(text, url) {
  const esc = s => s.replace(/&/g, "&amp;").replace(/</g, "&lt;").replace(/>/g, "&gt;").replace(/"/g, "&quot;");
  const inline = s => esc(s)
    .replace(/!\[([^\]]*)\]\(([^)]+)\)/g, (m, alt, src) => `<img alt="${alt}" src="${esc(url(src))}">`)
    .replace(/\[([^\]]+)\]\(([^)]+)\)/g, (m, label, href) => `<a href="${esc(url(href))}">${label}</a>`)
    .replace(/`([^`]+)`/g, "<code>$1</code>");
  const html = [];
  const lines = text.split("\n");
  for (let i = 0; i < lines.length; i++) {
    const line = lines[i];
    const heading = line.match(/^(#{1,4}) (.*)/);
    if (heading) html.push(`<h${heading[1].length + 1}>${inline(heading[2])}</h${heading[1].length + 1}>`);
    else if (line.startsWith("|")) {
      const rows = [];
      for (; i < lines.length && lines[i].startsWith("|"); i++) rows.push(lines[i]);
      i--;
      const cells = r => r.replace(/^\||\|$/g, "").split("|").map(c => c.trim());
      html.push("<table><tr>" + cells(rows[0]).map(c => `<th>${inline(c)}</th>`).join("") + "</tr>" +
        rows.slice(2).map(r => "<tr>" + cells(r).map(c => `<td>${inline(c)}</td>`).join("") + "</tr>").join("") + "</table>");
    } else if (line.trim()) html.push(`<p>${inline(line)}</p>`);
  }
  return html.join("\n");
}

async function refreshJobs() {
  let jobs;
  try { jobs = await api("/api/jobs"); } catch (e) { return; }
  for (const job of jobs.slice().reverse()) {
    let c = state.cards[job.id];
    if (!c) {
      const list = document.querySelector(`.jobs[data-kinds~="${job.kind}"]`);
      if (!list) continue;
      c = state.cards[job.id] = card(job);
      $(".empty", list)?.remove();
      list.prepend(c.node);
    }
    updateCard(c, job);
  }
}

async function main() {
  state.config = await api("/api/config");
  $("#cache-folder").textContent = `in ${state.config.cache} (shared with \`dancesynth dance --target\`)`;
  $("#train-preset").replaceChildren(...state.config.presets.map(p => el("option", { value: p.name, text: p.label })));
  for (const b of document.querySelectorAll("nav button")) b.addEventListener("click", () => showTab(b.dataset.tab));
  showTab(["dance", "models", "demo"].includes(location.hash.slice(1)) ? location.hash.slice(1) : "dance");
  uploader($("#song-file"), "song", $("#song-status"), () => { $("input[name=song-source][value=upload]").checked = true; });
  uploader($("#dance-video"), "video", $("#dance-video-status"), () => { $("input[name=target-source][value=video]").checked = true; });
  uploader($("#train-video"), "video", $("#train-video-status"));
  $("#builtin-song").addEventListener("change", () => { $("input[name=song-source][value=builtin]").checked = true; });
  $("#dance-model").addEventListener("change", () => { $("input[name=target-source][value=model]").checked = true; });
  $("#dance-form").addEventListener("submit", dance);
  $("#train-form").addEventListener("submit", e => {
    e.preventDefault();
    try { train({ video: uploaded("train-video", "a video of the person") }, $("#train-error")); }
    catch (err) { $("#train-error").textContent = err.message; }
  });
  $("#preview-button").addEventListener("click", () => {
    try { startJob({ kind: "preview", video: uploaded("train-video", "a video of the person") }, $("#train-error")); }
    catch (err) { $("#train-error").textContent = err.message; }
  });
  $("#demo-form").addEventListener("submit", e => {
    e.preventDefault();
    startJob({ kind: "demo", minutes: $("#demo-minutes").value }, $("#demo-error"), $("#demo-button"));
  });
  await Promise.all([loadModels(), loadPoseModels(), refreshJobs()]);
  setInterval(refreshJobs, POLL_MS);
  document.body.dataset.ready = "1";
  loadSongs().catch(e => { $("#builtin-song").replaceChildren(el("option", { value: "", text: e.message })); });
}

main();
