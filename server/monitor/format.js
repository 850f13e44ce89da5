// Small display helpers shared by the pages.
import { FINAL_JOB_STATES } from './protocol.js';

export function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === undefined || v === null || v === false) continue;
    if (k === 'class') e.className = v;
    else if (k === 'text') e.textContent = v;
    else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
    else if (k === 'dataset') Object.assign(e.dataset, v);
    else e.setAttribute(k, v === true ? '' : v);
  }
  for (const c of children.flat(Infinity)) if (c !== null && c !== undefined) e.append(c);
  return e;
}

export function duration(seconds) {
  if (seconds === null || seconds === undefined || !isFinite(seconds)) return '–';
  const s = Math.max(0, Math.round(seconds));
  if (s < 60) return s + ' s';
  if (s < 3600) return Math.floor(s / 60) + ' min ' + String(s % 60).padStart(2, '0') + ' s';
  return Math.floor(s / 3600) + ' h ' + String(Math.floor(s % 3600 / 60)).padStart(2, '0') + ' min';
}

export function clock(ms) {
  if (!ms) return '–';
  const d = new Date(ms);
  const today = new Date();
  const time = d.toLocaleTimeString([], { hour: '2-digit', minute: '2-digit', second: '2-digit' });
  return d.toDateString() === today.toDateString() ? time : d.toLocaleDateString() + ' ' + time;
}

export function ago(ms) {
  if (!ms) return '–';
  return duration((Date.now() - ms) / 1000) + ' ago';
}

/** Whether a job is paused, however the coordinator reports it. */
export function isPaused(job) { return job.state === 'paused' || job.paused === true; }

export function shownState(job) { return isPaused(job) && job.state !== 'paused' ? 'paused' : job.state; }

export function badge(state) { return el('span', { class: 'badge state-' + state, text: state }); }

/**
 * The page of a job as the monitor's address names it: a sequence's frame strip (#/jobs/ID/frames), a frame's place
 * in its sequence's strip (#/jobs/SEQ/frames/N), or a one-image job's page (#/jobs/ID). app.js reads these back.
 */
export function jobHref(job) {
  const id = (s) => encodeURIComponent(s);
  if (job.frames) return `#/jobs/${id(job.id)}/frames`;
  if (job.sequence) return `#/jobs/${id(job.sequence)}/frames/${job.frame}`;
  return `#/jobs/${id(job.id)}`;
}

/** A sequence's frames done of its total ("12/24 frames"), or null for a job that is not a sequence. */
export function framesDone(job) {
  return job.frames ? `${job.frames.done}/${job.frames.total} frames` : null;
}

/** Applies a tile_leased or tile_done event to a job's tile counts (GET /v1/jobs/{id}'s `tiles`). */
export function countTileEvent(tiles, type) {
  if (type === 'tile_leased') { tiles.pending = Math.max(0, tiles.pending - 1); tiles.leased += 1; }
  else if (type === 'tile_done') { tiles.leased = Math.max(0, tiles.leased - 1); tiles.done = Math.min(tiles.total, tiles.done + 1); }
}

// When each job status arrived (performance.now()), so that the figures of a job that has started go on counting
// between the coordinator's answers: its render_seconds is the wall time since its first lease as of the answer.
const received = new WeakMap();

/** Records that `job` (a status from the coordinator) arrived now; returns it. */
export function arrived(job) {
  received.set(job, performance.now());
  return job;
}

/** The states a job ends in (protocol.js, served by the coordinator). */
export const FINAL = FINAL_JOB_STATES;

/** Whether a job's clock runs (it has started and not ended): its page redraws its figures every second. */
export function clockRuns(job) {
  return Boolean(job.started_ms) && !FINAL.includes(job.state);
}

/**
 * A job's progress, elapsed seconds (extrapolated from its status's arrival while its clock runs), ETA (the elapsed
 * time per tile done so far, times the tiles left; tile events keep the counts current) and Mrays/s (the status's
 * rays over its render time).
 */
export function jobFigures(job) {
  const t = job.tiles || { total: 0, done: 0 };
  const frac = t.total ? t.done / t.total : 0;
  const reported = job.render_seconds || 0;
  const at = received.get(job);
  const secs = clockRuns(job) && at !== undefined ? reported + (performance.now() - at) / 1000 : reported;
  let eta = null;
  if ((job.state === 'running') && t.done > 0 && secs > 0) eta = secs / t.done * (t.total - t.done);
  if (job.state === 'done') eta = 0;
  const mrays = reported > 0 && job.rays ? job.rays / reported / 1e6 : null;
  return { frac, eta, mrays, secs };
}

/** A job's tiles done as a bar; a sequence's frames done under it unless `withFrames` is false. */
export function progressBar(job, withFrames = true) {
  const t = job.tiles || { total: 0, done: 0, leased: 0 };
  const pct = t.total ? 100 * t.done / t.total : 0;
  const leasedPct = t.total ? 100 * (t.leased || 0) / t.total : 0;
  const bar = el('div', { class: 'progress', title: `${t.done} of ${t.total} tiles done, ${t.leased || 0} rendering` },
    el('div', { class: 'progress-done state-' + shownState(job) }),
    el('div', { class: 'progress-leased' }));
  bar.children[0].style.width = pct.toFixed(2) + '%';
  bar.children[1].style.width = leasedPct.toFixed(2) + '%';
  const cell = el('div', { class: 'progress-cell' }, bar, el('span', { class: 'progress-text', text: `${t.done}/${t.total}` }));
  // A sequence's frames done, under its tiles' bar.
  return job.frames && withFrames
    ? el('div', {}, cell, el('div', { class: 'progress-frames', text: framesDone(job), title: 'Frames done of the sequence\'s frames' }))
    : cell;
}

/** "1 tile", "3 tiles". */
export function plural(n, word) { return `${n.toLocaleString('en-US')} ${word}${n === 1 ? '' : 's'}`; }

export function mrays(v) { return v === null || v === undefined ? '–' : v >= 100 ? v.toFixed(0) : v.toFixed(1); }

/** How a job samples, from its spec's settings (GET /v1/jobs/{id}/spec): adaptive or fixed, and what it overrides. */
export function samplingText(spec) {
  if (!spec) return '–';
  const parts = [spec.target_error
    ? `adaptive to ${spec.target_error} relative error, ${spec.min_spp}–${spec.max_spp} spp`
    : 'fixed spp'];
  if (spec.error_floor !== undefined) parts.push(`error floor ${spec.error_floor}`);
  if (spec.replicates > 1) parts.push(`${spec.replicates} replicates`);
  if (spec.integrator) parts.push(`${spec.integrator} integrator`);
  for (const [key, name] of [['area_sampling', 'area lights'], ['env_sampling', 'environment'], ['bvh', 'BVH']])
    if (spec[key]) parts.push(`${name}: ${spec[key]}`);
  return parts.join(' · ');
}

/**
 * Whether the caller (`me`, GET /v1/me) may use monitor control `cap` on `job` (or on any job when none is given):
 * its role allows it on every job, or on its own and the job is its. Returns '' when it may, else why not.
 */
export function refusedControl(me, cap, job) {
  const scope = me && me.controls ? me.controls[cap] : 'any';
  if (scope === 'any' || scope === undefined) return '';
  if (scope === 'own' && (!job || job.owner === me.user)) return '';
  if (scope === 'own') return `Only its owner (${job.owner || 'unknown'}) or an admin may do this; you are ${me.user}.`;
  return `Your role (${me.role}) may not do this.`;
}
