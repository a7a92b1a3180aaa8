// The kinesplat studio page (docs/studio.md): upload a photo, follow create's progress, play and
// download the avatars of the workspace. Plain ES module, no dependencies; the state comes from
// the server (/api/state, /api/events) and the page only draws it. window.studio holds what the
// browser test reads.
const $ = (id) => document.getElementById(id);
const studio = (window.studio = { state: null, selected: null, message: "", messageKind: "", events: 0 });

const STATE_WORDS = {
  queued: "queued",
  running: "being made",
  done: "made",
  failed: "failed",
  cancelled: "cancelled",
  interrupted: "interrupted",
};

function mb(bytes) {
  const m = bytes / (1024 * 1024);
  return (m < 10 && bytes % (1024 * 1024) !== 0 ? m.toFixed(1) : m.toFixed(0)) + " MB";
}

function clock(seconds) {
  if (seconds == null || seconds < 0) return "…";
  const s = Math.round(seconds);
  return `${Math.floor(s / 60)}:${String(s % 60).padStart(2, "0")}`;
}

function say(text, kind = "") {
  studio.message = text;
  studio.messageKind = kind;
  const m = $("message");
  m.textContent = text;
  m.className = kind;
}

async function api(method, url, body, headers = {}) {
  const r = await fetch(url, { method, body, headers });
  let j = null;
  try {
    j = await r.json();
  } catch {
    j = { error: `${r.status} ${r.statusText}` };
  }
  if (!r.ok) throw new Error(j.error || `${r.status} ${r.statusText}`);
  return j;
}

// ---- uploading -------------------------------------------------------------------------------

async function upload(file) {
  const limit = studio.state?.limits?.photo_bytes;
  if (limit && file.size > limit) {
    say(`${file.name}: refused: the photo is ${mb(file.size)}, over the ${mb(limit)} the studio takes`, "error");
    return;
  }
  say(`uploading ${file.name} (${mb(file.size)})…`);
  try {
    const j = await api("POST", "/api/avatars", file, { "X-Filename": encodeURIComponent(file.name) });
    await refresh(); // a state that has it, before it is selected
    studio.selected = j.id;
    draw();
    say(`${file.name}: uploaded; making the avatar`, "ok");
  } catch (e) {
    say(`${file.name}: refused: ${e.message}`, "error");
  }
}

const drop = $("drop");
$("file").addEventListener("change", (ev) => {
  const f = ev.target.files[0];
  ev.target.value = "";
  if (f) upload(f);
});
for (const t of ["dragenter", "dragover"])
  drop.addEventListener(t, (ev) => {
    ev.preventDefault();
    drop.classList.add("over");
  });
for (const t of ["dragleave", "drop"]) drop.addEventListener(t, () => drop.classList.remove("over"));
drop.addEventListener("drop", (ev) => {
  ev.preventDefault();
  const f = ev.dataTransfer.files[0];
  if (f) upload(f);
});
drop.addEventListener("keydown", (ev) => {
  if (ev.key === "Enter" || ev.key === " ") $("file").click();
});

// ---- actions ---------------------------------------------------------------------------------

async function action(method, suffix, done) {
  const id = studio.selected;
  if (!id) return;
  try {
    await api(method, `/api/avatars/${id}${suffix}`);
    if (done) say(done, "ok");
    await refresh();
  } catch (e) {
    say(e.message, "error");
  }
}
$("cancel").onclick = () => action("POST", "/cancel", "cancelled");
$("resume").onclick = () => action("POST", "/resume", "resumed: stages already made are skipped");
$("delete").onclick = () => {
  const a = current();
  if (a && confirm(`Delete "${a.label}" and everything made from it?`)) {
    action("DELETE", "", `deleted ${a.label}`).then(() => {
      studio.selected = null;
      draw();
    });
  }
};

// ---- drawing ---------------------------------------------------------------------------------

function current() {
  return studio.state?.avatars.find((a) => a.id === studio.selected) || null;
}

function drawList() {
  const ul = $("avatars");
  const avatars = studio.state?.avatars || [];
  $("empty").hidden = avatars.length > 0;
  ul.replaceChildren(
    ...avatars.map((a) => {
      const li = document.createElement("li");
      li.dataset.id = a.id;
      li.dataset.state = a.state;
      if (a.id === studio.selected) li.className = "selected";
      const img = document.createElement("img");
      img.src = a.photo;
      img.alt = "";
      img.loading = "lazy";
      const info = document.createElement("div");
      info.className = "info";
      const name = document.createElement("div");
      name.className = "name";
      name.textContent = a.label;
      const sub = document.createElement("div");
      sub.className = "sub";
      const badge = document.createElement("span");
      badge.className = `badge ${a.state}`;
      badge.textContent = STATE_WORDS[a.state] || a.state;
      sub.append(badge, " ", a.created.replace("T", " ").replace("Z", " UTC"));
      info.append(name, sub);
      if (a.state === "running" && a.progress) {
        const bar = document.createElement("div");
        bar.className = "mini";
        const fill = document.createElement("div");
        fill.style.width = `${a.progress.percent.toFixed(1)}%`;
        bar.append(fill);
        info.append(bar);
      }
      li.append(img, info);
      li.onclick = () => {
        studio.selected = a.id;
        draw();
      };
      return li;
    }),
  );
}

function setSrc(el, url) {
  // Only when it changes: a new src reloads (the viewer would start over).
  if ((el.dataset.src || "") !== (url || "")) {
    el.dataset.src = url || "";
    if (url) el.src = url;
    else el.removeAttribute("src");
  }
}

function drawProgress(a) {
  const p = a.progress;
  const show = a.state === "running" || a.state === "queued";
  $("progress").hidden = !show;
  if (!show) return;
  if (a.state === "queued") {
    $("bar-fill").style.width = "0%";
    $("progress-text").textContent = `queued: ${a.position === 1 ? "next" : `number ${a.position}`} in line`;
    $("stages").replaceChildren();
    $("last-line").textContent = "";
    return;
  }
  $("bar-fill").style.width = `${p.percent.toFixed(1)}%`;
  const stage = p.stages.find((s) => s.status === "running");
  const stageText = stage ? `${stage.name} ${Math.round(stage.percent)}%` : "";
  $("progress-text").textContent =
    `${Math.round(p.percent)}%` +
    (stageText ? ` — ${stageText}` : "") +
    ` — elapsed ${clock(p.elapsed)}, remaining ${p.remaining == null ? "estimating…" : "about " + clock(p.remaining)}` +
    (a.cancelling ? " — cancelling…" : "");
  $("stages").replaceChildren(
    ...p.stages.map((s) => {
      const li = document.createElement("li");
      li.className = s.status;
      li.dataset.stage = s.name;
      li.textContent = s.status === "running" ? `${s.name} ${Math.round(s.percent)}%` : s.name;
      return li;
    }),
  );
  $("last-line").textContent = p.last_line || "";
}

function drawMade(a) {
  const made = a.state === "done" && a.viewer;
  $("made").hidden = !made;
  if (!made) {
    setSrc($("viewer"), null);
    return;
  }
  setSrc($("viewer"), a.viewer);
  $("viewer-open").href = a.viewer;
  setSrc($("perceive-overlay"), a.files["perceive_overlay.png"]);
  setSrc($("fit-overlay"), a.files["fit_overlay.png"]);
  const vids = $("videos");
  const key = a.videos.map((v) => v.url).join(" ");
  if (vids.dataset.key !== key) {
    vids.dataset.key = key;
    vids.replaceChildren(
      ...a.videos.map((v) => {
        const fig = document.createElement("figure");
        const video = document.createElement("video");
        video.src = v.url;
        video.controls = true;
        video.loop = true;
        video.muted = true;
        video.preload = "metadata";
        const cap = document.createElement("figcaption");
        const link = document.createElement("a");
        link.href = v.url + "?download=1";
        link.textContent = `${v.name}.mp4`;
        cap.append(link);
        fig.append(video, cap);
        return fig;
      }),
    );
  }
  $("downloads").replaceChildren(
    ...a.downloads.map((d) => {
      const li = document.createElement("li");
      const link = document.createElement("a");
      link.href = d.url;
      link.dataset.name = d.name;
      link.textContent = d.label;
      li.append(link, ` — ${mb(d.bytes)}`);
      return li;
    }),
  );
}

function draw() {
  drawList();
  const a = current();
  $("detail").hidden = !a;
  if (!a) return;
  $("d-label").textContent = a.label;
  $("d-id").textContent = a.id;
  const badge = $("d-state");
  badge.className = `badge ${a.state}`;
  badge.textContent = STATE_WORDS[a.state] || a.state;
  $("cancel").hidden = !(a.state === "running" || a.state === "queued");
  $("resume").hidden = !["failed", "cancelled", "interrupted"].includes(a.state);
  $("delete").hidden = a.state === "running" || a.state === "queued";
  const failed = ["failed", "cancelled", "interrupted"].includes(a.state);
  $("failure").hidden = !failed;
  if (failed) {
    const where = a.error_stage ? ` in the ${a.error_stage} stage` : "";
    $("failure-title").textContent =
      a.state === "failed"
        ? `create failed${where}:`
        : a.state === "cancelled"
          ? `cancelled${where}; resume goes on from there:`
          : `interrupted${where} (the studio was stopped); resume goes on from there`;
    $("failure-line").textContent = a.state === "interrupted" ? "" : a.error || "";
  }
  drawProgress(a);
  drawMade(a);
  setSrc($("d-photo"), a.photo);
}

// ---- state from the server -------------------------------------------------------------------

function take(state) {
  // The event stream and the polls may cross: an older state than the one shown is dropped.
  if (studio.state && state.version < studio.state.version) return;
  studio.state = state;
  $("workspace").textContent = state.workspace;
  if (studio.selected && !state.avatars.some((a) => a.id === studio.selected)) studio.selected = null;
  if (!studio.selected && state.avatars.length) studio.selected = state.avatars[0].id;
  draw();
}

async function refresh() {
  try {
    take(await api("GET", "/api/state"));
    $("connection").textContent = "";
  } catch (e) {
    $("connection").textContent = `not connected (${e.message})`;
  }
}

let lastEvent = 0;
function listen() {
  const es = new EventSource("/api/events");
  es.addEventListener("state", (ev) => {
    lastEvent = Date.now();
    studio.events++;
    $("connection").textContent = "";
    take(JSON.parse(ev.data));
  });
  es.addEventListener("ping", () => {
    lastEvent = Date.now();
  });
  es.onerror = () => {
    $("connection").textContent = "reconnecting…";
  };
}
// Polling as well when the event stream is quiet (refused, or a proxy in the way).
setInterval(() => {
  if (Date.now() - lastEvent > 8000) refresh();
}, 2000);

await refresh();
listen();
