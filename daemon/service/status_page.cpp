#include "service/status_page.h"

namespace mm::service {

// Everything from outside (names, reasons) goes into the page as text nodes, never as HTML.
const char* const kStatusPageHtml = R"HTML(<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>meshmark status</title>
<style>
  body { font: 14px/1.4 system-ui, sans-serif; margin: 1.5em; color: #222; }
  h1 { font-size: 1.4em; margin: 0 0 .3em; } h2 { font-size: 1.1em; margin: 1.4em 0 .4em; }
  .counts { display: flex; gap: 1em; flex-wrap: wrap; }
  .count { border: 1px solid #ccc; border-radius: 6px; padding: .5em 1em; min-width: 6em; }
  .count b { display: block; font-size: 1.6em; }
  table { border-collapse: collapse; width: 100%; } td, th { border-bottom: 1px solid #eee; padding: .3em .5em; text-align: left; vertical-align: top; }
  .failed { color: #a00; } .succeeded { color: #070; } .reason { font-family: monospace; white-space: pre-wrap; }
  #login { display: none; } .muted { color: #777; } button { margin-right: .3em; }
</style>
</head>
<body>
<h1>meshmark</h1>
<div id="who" class="muted"></div>
<form id="login"><label>API token <input id="token" type="password" size="70" autocomplete="off"></label> <button>Show</button>
  <div id="login-error" class="failed"></div></form>
<div id="main" hidden>
  <div class="counts" id="counts"></div>
  <h2>Jobs</h2>
  <form id="filters">
    <select id="f-kind"><option value="">any kind</option><option>protect</option><option>detect</option><option>evidence</option><option>webhook</option></select>
    <select id="f-state"><option value="">any state</option><option>queued</option><option>running</option><option>retrying</option><option>succeeded</option><option>failed</option><option>cancelled</option></select>
    <input id="f-name" placeholder="part file name"> <button>Filter</button>
  </form>
  <table id="jobs"><thead><tr><th>id</th><th>kind</th><th>state</th><th>part</th><th>customer</th><th>attempts</th><th>created</th><th></th></tr></thead><tbody></tbody></table>
  <h2>Failures</h2>
  <table id="failures"><thead><tr><th>id</th><th>kind</th><th>part</th><th>reason</th></tr></thead><tbody></tbody></table>
  <h2>Detections</h2>
  <table id="detections"><thead><tr><th>id</th><th>suspect</th><th>verdict</th><th>customer</th><th>-log10 p</th><th>evidence</th></tr></thead><tbody></tbody></table>
</div>
<script>
"use strict";
const hash = new URLSearchParams(location.hash.slice(1));
if (hash.get("token")) { sessionStorage.setItem("meshmark-token", hash.get("token")); history.replaceState(null, "", location.pathname); }
let role = "";
async function api(path, method) {
  const r = await fetch(path, { method: method || "GET", headers: { "Authorization": "Bearer " + sessionStorage.getItem("meshmark-token") } });
  if (r.status === 401) { showLogin("the token is unknown or revoked"); throw new Error("unauthorized"); }
  return r;
}
function cell(row, text, cls) { const td = row.insertCell(); td.textContent = text === undefined || text === null ? "" : String(text); if (cls) td.className = cls; return td; }
function showLogin(message) {
  document.getElementById("main").hidden = true;
  document.getElementById("login").style.display = "block";
  document.getElementById("login-error").textContent = message || "";
}
document.getElementById("login").addEventListener("submit", e => { e.preventDefault(); sessionStorage.setItem("meshmark-token", document.getElementById("token").value.trim()); load(); });
document.getElementById("filters").addEventListener("submit", e => { e.preventDefault(); loadJobs(); });
async function act(id, action) { await api("/v1/jobs/" + id + "/" + action, "POST"); load(); }
async function download(path, name) {
  const r = await api(path);
  if (!r.ok) { alert((await r.json()).detail); return; }
  const a = document.createElement("a"); a.href = URL.createObjectURL(await r.blob()); a.download = name; a.click();
}
async function loadJobs() {
  const q = new URLSearchParams({ limit: "50" });
  for (const k of ["kind", "state", "name"]) { const v = document.getElementById("f-" + k).value.trim(); if (v) q.set(k, v); }
  const jobs = (await (await api("/v1/jobs?" + q)).json()).jobs || [];
  const body = document.querySelector("#jobs tbody"); body.replaceChildren();
  for (const j of jobs) {
    const row = body.insertRow();
    cell(row, j.id); cell(row, j.kind); cell(row, j.state, j.state); cell(row, j.name); cell(row, j.customer);
    cell(row, j.attempts + "/" + j.max_attempts); cell(row, j.created_at);
    const actions = row.insertCell();
    if (role === "admin" && ["queued", "running", "retrying"].includes(j.state)) {
      const b = document.createElement("button"); b.textContent = "cancel"; b.onclick = () => act(j.id, "cancel"); actions.appendChild(b);
    }
    if (role === "admin" && ["failed", "retrying", "cancelled"].includes(j.state)) {
      const b = document.createElement("button"); b.textContent = "retry"; b.onclick = () => act(j.id, "retry"); actions.appendChild(b);
    }
  }
}
async function load() {
  try {
    const me = await (await api("/v1/me")).json();
    role = me.role;
    document.getElementById("who").textContent = "token " + me.name + " (" + me.role + ")";
    document.getElementById("login").style.display = "none";
    document.getElementById("main").hidden = false;
    const counts = await (await api("/v1/queue")).json();
    const box = document.getElementById("counts"); box.replaceChildren();
    for (const s of ["queued", "running", "retrying", "succeeded", "failed", "cancelled"]) {
      const d = document.createElement("div"); d.className = "count"; d.id = "count-" + s;
      const b = document.createElement("b"); b.textContent = counts[s]; d.appendChild(b); d.appendChild(document.createTextNode(s)); box.appendChild(d);
    }
    await loadJobs();
    const failed = (await (await api("/v1/jobs?state=failed&limit=20")).json()).jobs || [];
    const fb = document.querySelector("#failures tbody"); fb.replaceChildren();
    for (const j of failed) { const row = fb.insertRow(); cell(row, j.id); cell(row, j.kind); cell(row, j.name); cell(row, j.error, "reason"); }
    const dets = (await (await api("/v1/jobs?kind=detect&state=succeeded&limit=20")).json()).jobs || [];
    const db = document.querySelector("#detections tbody"); db.replaceChildren();
    for (const j of dets) {
      const r = j.result || {}; const row = db.insertRow();
      cell(row, j.id); cell(row, j.name); cell(row, r.verdict); cell(row, r.customer);
      cell(row, r.neg_log10_p === undefined ? "" : Number(r.neg_log10_p).toFixed(1));
      const ev = row.insertCell();
      if (r.verdict === "attributed") {
        const b = document.createElement("button"); b.textContent = "package";
        b.onclick = () => download("/v1/jobs/" + j.id + "/evidence", "evidence-" + j.id + ".tar"); ev.appendChild(b);
      }
    }
  } catch (e) { if (e.message !== "unauthorized") document.getElementById("who").textContent = "could not load: " + e.message; }
}
if (sessionStorage.getItem("meshmark-token")) load(); else showLogin();
</script>
</body>
</html>
)HTML";

}  // namespace mm::service
