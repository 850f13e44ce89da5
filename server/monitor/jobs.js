// The job list: state (and what a job waits for), owner, progress, priority, elapsed time, ETA and Mrays/s of every
// job, filtered by state and, with "my jobs", by owner. A sequence is one row (its frames done under its tiles' bar);
// its frames' own jobs are not listed.
import * as api from './api.js';
import { el, badge, duration, clock, jobFigures, progressBar, mrays, shownState, arrived, clockRuns, jobHref,
  countTileEvent } from './format.js';

const STATES = ['all', ...api.JOB_STATES];

export function mount(host, ctx) {
  let filter = sessionStorage.getItem('tessera.jobFilter') || 'all';
  let mineOnly = sessionStorage.getItem('tessera.mine') === 'true';
  const chips = el('div', { class: 'chips', role: 'tablist', 'aria-label': 'Filter by state' });
  const mine = el('label', { class: 'mine' }, el('input', {
    type: 'checkbox', id: 'my-jobs', checked: mineOnly || undefined,
    onchange: (ev) => { mineOnly = ev.target.checked; sessionStorage.setItem('tessera.mine', String(mineOnly)); draw(); },
  }), ' my jobs');
  const me = ctx && ctx.me;
  const tbody = el('tbody');
  const empty = el('p', { class: 'empty', hidden: true });
  host.append(
    el('div', { class: 'page-head' }, el('h1', { text: 'Jobs' }), chips, me ? mine : ''),
    el('div', { class: 'card' },
      el('table', { class: 'jobs', id: 'jobs-table' },
        el('thead', {}, el('tr', {},
          ['Job', 'State', 'Owner', 'Progress', 'Priority', 'Elapsed', 'ETA', 'Mrays/s', 'Size', 'Submitted']
            .map((h, i) => el('th', { text: h, class: i >= 4 && i <= 7 ? 'num' : undefined })))),
        tbody),
      empty));

  let jobs = [];
  // Frame jobs (their `job` events name their sequence) -> their sequence, so that their tile events move its row.
  const sequenceOf = new Map();
  // Elapsed times and ETAs of running jobs go on between answers and events.
  const ticker = setInterval(() => { if (jobs.some(clockRuns)) draw(); }, 1000);
  function draw() {
    const counts = Object.fromEntries(STATES.map((s) => [s, 0]));
    const listed = jobs.filter((j) => !mineOnly || !me || j.owner === me.user);
    for (const j of listed) { counts.all++; counts[shownState(j)] = (counts[shownState(j)] || 0) + 1; }
    chips.replaceChildren(...STATES.map((s) => el('button', {
      type: 'button', class: 'chip' + (s === filter ? ' active' : ''), 'data-state': s, role: 'tab',
      'aria-selected': s === filter ? 'true' : 'false',
      onclick: () => { filter = s; sessionStorage.setItem('tessera.jobFilter', s); draw(); },
    }, s, el('span', { class: 'count', text: String(counts[s] || 0) }))));
    const shown = listed.filter((j) => filter === 'all' || shownState(j) === filter);
    tbody.replaceChildren(...shown.map(row));
    empty.hidden = shown.length > 0;
    empty.textContent = jobs.length ? 'No ' + filter + ' jobs.' : 'No jobs yet. Submit one with tessera submit SCENE --coordinator URL.';
  }

  function row(j) {
    const f = jobFigures(j);
    const href = jobHref(j);
    const open = () => { location.hash = href; };
    return el('tr', { class: 'clickable', 'data-job': j.id, 'data-sequence': j.frames ? 'true' : undefined, onclick: open },
      el('td', {}, el('a', { href, class: 'job-name', text: j.name || j.id }),
        el('div', { class: 'sub', text: j.frames ? `${j.id} · sequence, frames ${j.frames.first}–${j.frames.last}` : j.id })),
      el('td', {}, badge(shownState(j)),
        j.waiting_for ? el('div', { class: 'sub waiting', text: 'waiting for ' + j.waiting_for }) : ''),
      el('td', { class: 'owner', text: j.owner || '–' }),
      el('td', {}, progressBar(j)),
      el('td', { class: 'num', text: String(j.priority ?? 0) }),
      el('td', { class: 'num', text: duration(f.secs) }),
      el('td', { class: 'num', text: f.eta === null ? '–' : duration(f.eta) }),
      el('td', { class: 'num', text: mrays(f.mrays) }),
      el('td', { class: 'sub', text: `${j.width}×${j.height}, ${j.spp} spp` }),
      el('td', { class: 'sub', text: clock(j.created_ms) }));
  }

  return {
    async refresh() {
      const body = await api.call('GET', api.route('jobs'));
      jobs = (body.jobs || []).map(arrived);
      draw();
    },
    /** Applies an event of the stream (true: applied, no refresh needed). */
    onEvent(type, d) {
      if (type === 'job') {
        // A frame's job is no row of its own: its sequence's row changes with the sequence's own event, which follows.
        if (d.sequence) { sequenceOf.set(d.id, d.sequence); return true; }
        const i = jobs.findIndex((j) => j.id === d.id);
        if (i >= 0) jobs[i] = arrived(d);
        else jobs.unshift(arrived(d));
        draw();
        return true;
      }
      if (type === 'tile_leased' || type === 'tile_done') {
        const owner = sequenceOf.get(d.job) || d.job;
        const j = jobs.find((x) => x.id === owner);
        if (!j) return false;
        countTileEvent(j.tiles, type);
        draw();
        return true;
      }
      if (type === 'frame_done') return true;  // the sequence's job event carries its frame counts
      return type !== 'tile_failed';  // a failure may change the job: refresh; worker events are not shown here
    },
    unmount() { clearInterval(ticker); },
  };
}
