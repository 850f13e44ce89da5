// A sequence: its figures and controls (acting on all its frames), the frame strip (a window of its frames, paged
// through GET /v1/jobs/{id}/frames), and the chosen frame's job in the job view (its tile map, image and tiles).
import * as api from './api.js';
import { el, badge, duration, clock, jobFigures, progressBar, mrays, shownState, arrived, clockRuns, jobHref,
  countTileEvent, plural } from './format.js';
import { JobControls, actor, fetchJob } from './controls.js';
import { FrameStrip } from './framestrip.js';
import { PipelineView } from './pipeline.js';
import * as jobView from './job.js';

const PAGE = 60;  // frames in the strip's window

const count = (n) => n.toLocaleString('en-US');

export function mount(host, ctx) {
  const id = ctx.arg;
  const path = api.route('job', id);
  let seq = null, mounted = true, deleted = false;
  // The window: the frames listed after `winAfter` (null: from the first), and the cursor of the page after it.
  let win = [], winAfter = null, winNext = null;
  let selected = null;              // the chosen frame's number
  let frameView = null, frameJob = null;  // the job view of the chosen frame, and that frame's job id
  const ours = new Set();           // the frame jobs seen, so that their tile events move the sequence's counts
  let reloadTimer = null;

  const title = el('h1', { id: 'seq-title', text: id });
  const stateBadge = el('span', { id: 'seq-state' });
  const kind = el('span', { class: 'sub', id: 'seq-kind' });
  const actionMsg = el('p', { class: 'action-msg', id: 'seq-action-msg', role: 'status' });
  const figures = el('dl', { class: 'figures', id: 'seq-figures' });
  const errorBox = el('div', { class: 'errorbox', id: 'seq-error', hidden: true });
  const pipeline = new PipelineView('seq');
  const act = actor(actionMsg, ctx.refresh);
  const controls = new JobControls(ctx, id, act, () => { deleted = true; location.hash = '#/jobs'; });
  controls.element.id = 'seq-actions';

  const strip = new FrameStrip((f) => choose(f.frame));
  const legend = el('div', { class: 'legend', id: 'frame-legend' });
  const prevB = el('button', { type: 'button', class: 'ghost', text: '‹ Earlier', 'data-page': 'prev', onclick: () => page(-1) });
  const nextB = el('button', { type: 'button', class: 'ghost', text: 'Later ›', 'data-page': 'next', onclick: () => page(1) });
  const range = el('span', { class: 'sub', id: 'frame-range' });
  const gotoInput = el('input', { type: 'number', id: 'frame-goto', step: '1', 'aria-label': 'Frame number', placeholder: 'frame' });
  const gotoForm = el('form', { class: 'goto', onsubmit: (ev) => {
    ev.preventDefault();
    if (gotoInput.value !== '') choose(Number(gotoInput.value));
  } }, gotoInput, el('button', { type: 'submit', class: 'ghost', text: 'Go' }));
  const frameHost = el('div', { id: 'frame-view', class: 'frame-view' });
  const frameNote = el('p', { class: 'empty', id: 'frame-note', text: 'Choose a frame in the strip for its tiles and image.' });

  host.append(
    el('div', { class: 'crumbs' }, el('a', { href: '#/jobs', text: 'Jobs' }), ' / ', el('span', { text: id })),
    el('div', { class: 'page-head' }, el('div', { class: 'title' }, title, stateBadge, kind), controls.element),
    actionMsg, errorBox, pipeline.element,
    el('div', { class: 'card figures-card' }, figures),
    el('section', { class: 'card strip-card' },
      el('div', { class: 'card-head' },
        el('div', { class: 'strip-title' }, el('h2', { text: 'Frames' }), legend),
        el('div', { class: 'pager' }, range, prevB, nextB, gotoForm)),
      strip.element),
    frameNote, frameHost);

  const ticker = setInterval(() => { if (seq && clockRuns(seq)) drawHead(); }, 1000);

  function drawHead() {
    title.textContent = seq.name || seq.id;
    stateBadge.replaceChildren(badge(shownState(seq)));
    const fc = seq.frames;
    kind.textContent = `sequence of ${plural(fc.total, 'frame')}`;
    const f = jobFigures(seq);
    const t = seq.tiles;
    // Besides those done, the frames that are neither done nor waiting their turn.
    const others = api.JOB_STATES.filter((s) => s !== 'done' && s !== 'queued' && fc[s]).map((s) => `${count(fc[s])} ${s}`);
    const item = (k, v, idAttr) => [el('dt', { text: k }), el('dd', { text: v, id: idAttr })];
    figures.replaceChildren(
      el('div', { class: 'fig wide' }, el('dt', { text: 'Progress' }), el('dd', {}, progressBar(seq, false))),  // frames: the next figure
      ...[
        item('Frames', [`${count(fc.done)} / ${count(fc.total)} done`, ...others].join(' · '), 'fig-frames'),
        item('Tiles done', `${count(t.done)} / ${count(t.total)} (${Math.floor(100 * f.frac)}%)`, 'fig-done'),
        item('Rendering', plural(t.leased, 'tile'), 'fig-leased'),
        item('Elapsed', duration(f.secs)),
        item('ETA', f.eta === null ? '–' : duration(f.eta)),
        item('Mrays/s', mrays(f.mrays)),
        item('Image', `${seq.width}×${seq.height} · ${seq.spp} spp · seed ${seq.seed}`),
        item('Numbers', `${fc.first}–${fc.last}`),
        item('Order', String(seq.frame_order || '–').replace(/_/g, ' '), 'fig-order'),
        item('Priority', String(seq.priority ?? 0), 'fig-priority'),
        item('Owner', seq.owner || '–', 'fig-owner'),
        item('Submitted', clock(seq.created_ms)),
      ].map((pair) => el('div', { class: 'fig' }, pair)));
    errorBox.hidden = !seq.error;
    errorBox.textContent = seq.error ? 'Failed: ' + seq.error : '';
    pipeline.update(seq);
    controls.update(seq);
    legend.replaceChildren(...api.JOB_STATES.map((s) =>
      el('span', { class: 'key', 'data-count': s }, el('i', { class: 'swatch state-' + s }), `${s} ${count(fc[s] || 0)}`)));
  }

  // ---- the window of frames ----
  async function framesAfter(after, limit) {
    const q = new URLSearchParams({ limit: String(limit) });
    if (after !== null) q.set('after', String(after));
    return api.call('GET', api.route('job_frames', id) + '?' + q);
  }

  async function loadWindow(after) {
    const body = await framesAfter(after, PAGE);
    showWindow(body.frames || [], after, body.next ?? null);
  }

  function showWindow(frames, after, next) {
    win = frames;
    winAfter = after;
    winNext = next;
    for (const f of win) { arrived(f); ours.add(f.id); }
    drawWindow();
  }

  function drawWindow() {
    strip.show(win, seq.width, seq.height);
    const fc = seq.frames;
    prevB.disabled = !win.length || win[0].frame <= fc.first;
    nextB.disabled = winNext === null;
    range.textContent = win.length
      ? (win.length === fc.total ? `all ${count(fc.total)}` : `${win[0].frame}–${win[win.length - 1].frame} of ${count(fc.total)}`)
      : '';
  }

  // The mean step between frame numbers (1 when they are consecutive): where to start a window that holds a number.
  function step() {
    const fc = seq.frames;
    return fc.total > 1 ? Math.max(1, (fc.last - fc.first) / (fc.total - 1)) : 1;
  }

  /** Loads a window with frame `n` about in its middle (at its start when the numbers are unevenly spaced). */
  async function windowAround(n) {
    const first = seq.frames.first;
    n = Math.min(Math.max(n, first), seq.frames.last);
    // Near the end the window ends with the last frame, so that it is full.
    const after = Math.max(first - 1, Math.round(Math.min(n - 1 - Math.floor(PAGE / 2) * step(), seq.frames.last - PAGE * step())));
    const body = await framesAfter(after < first ? null : after, PAGE);
    const frames = body.frames || [];
    if (frames.some((f) => f.frame === n) || !frames.length || frames[0].frame > n) {
      showWindow(frames, after < first ? null : after, body.next ?? null);
      return;
    }
    await loadWindow(n - 1);
  }

  /** Shows the PAGE frames numbered below `s`: read forward from a guess of where they start (earlier each time the
   *  guess holds too few), keeping the last PAGE. */
  async function windowBefore(s) {
    const first = seq.frames.first;
    for (let span = PAGE * step(); ; span *= 4) {
      const from = Math.round(s - 1 - span);
      const start = from < first ? null : from;  // null: from the first frame
      let kept = [], after = start;
      for (;;) {
        const body = await framesAfter(after, PAGE);
        const frames = body.frames || [];
        kept = kept.concat(frames.filter((f) => f.frame < s)).slice(-PAGE);
        if (body.next == null || frames.some((f) => f.frame >= s)) break;
        after = body.next;
      }
      if (kept.length >= PAGE || start === null) {
        const head = kept.length ? kept[0].frame : s;
        // Listed after the number before its first frame; the page after it is the window shown before.
        showWindow(kept, head - 1 < first ? null : head - 1, kept.length ? kept[kept.length - 1].frame : null);
        return;
      }
    }
  }

  async function page(dir) {
    try {
      if (dir > 0 && winNext !== null) await loadWindow(winNext);
      else if (dir < 0 && win.length) await windowBefore(win[0].frame);
    } catch (e) {
      ctx.banner(e.message);
    }
  }

  // ---- the chosen frame ----
  /** Chooses frame `n` through the address (#/jobs/ID/frames/N), which brings route() and show(). */
  function choose(n) {
    const f = win.find((x) => x.frame === n);
    const href = f ? jobHref(f) : `${jobHref(seq)}/${n}`;
    if (location.hash === href) show(n).catch((e) => ctx.banner(e.message));
    else location.replace(href);
  }

  async function show(n) {
    if (!Number.isInteger(n)) return;
    if (!win.some((f) => f.frame === n)) await windowAround(n);
    const f = win.find((x) => x.frame === n);
    selected = n;
    strip.select(n);
    if (!f) {
      frameNote.textContent = `This sequence has no frame ${n} (its frames are numbered ${seq.frames.first} to ${seq.frames.last}).`;
      frameNote.hidden = false;
      return;
    }
    if (frameJob === f.id) return;
    if (frameView && frameView.unmount) frameView.unmount();
    frameHost.replaceChildren();
    frameJob = f.id;
    frameNote.hidden = true;
    frameView = jobView.mount(frameHost, { ...ctx, arg: f.id, embedded: true });
    await frameView.refresh();
  }

  /** The frame chosen when the address names none: a running one, else the last done, else the first shown. */
  function defaultFrame() {
    const running = win.find((f) => f.state === 'running');
    const done = win.filter((f) => f.state === 'done');
    return (running || done[done.length - 1] || win[0] || {}).frame;
  }

  function reloadSoon() {
    clearTimeout(reloadTimer);
    reloadTimer = setTimeout(() => { if (mounted && seq) loadWindow(winAfter).catch(() => {}); }, 200);
  }

  return {
    async refresh() {
      if (deleted) return;
      const j = await fetchJob(path, id, host, () => mounted);
      if (!j) return;
      if (!mounted) return;
      if (!j.frames) { location.replace(jobHref(j)); return; }  // not a sequence: the job page
      const firstTime = seq === null;
      seq = arrived(j);
      drawHead();
      if (firstTime) {
        // The window opens where the work is: about the first frame not yet ended (frames end roughly in order).
        const fc = seq.frames;
        const asked = ctx.frame === undefined ? NaN : Number(ctx.frame);
        const ended = fc.done + fc.failed + fc.cancelled;
        await windowAround(Number.isInteger(asked) ? asked : Math.min(fc.last, Math.round(fc.first + ended * step())));
        if (Number.isInteger(asked)) await show(asked);
        else if (defaultFrame() !== undefined) choose(defaultFrame());
        return;
      }
      await loadWindow(winAfter);
      if (frameView) await frameView.refresh();
    },
    /** The address changed within this page: another frame chosen. */
    route(r) {
      if (seq && r.frame !== undefined) show(Number(r.frame)).catch((e) => ctx.banner(e.message));
    },
    /** Applies an event of the stream (true: applied, no refresh needed). */
    onEvent(type, d) {
      if (!seq) return false;
      if (type === 'job') {
        if (d.id === id) {
          if (d.then && d.then.length) return false;  // its steps' outputs come with the job's own answer
          seq = arrived(d);
          drawHead();
          reloadSoon();  // a pause or resume of the sequence changes its frames without an event of theirs
          return true;
        }
        if (d.sequence !== id) return true;
        ours.add(d.id);
        const i = win.findIndex((f) => f.id === d.id);
        if (i >= 0) { win[i] = arrived(d); strip.update(win[i]); }
        if (frameView && d.id === frameJob) frameView.onEvent(type, d);
        return true;
      }
      if (type === 'frame_done') {
        if (d.job === id) strip.refreshThumb(d.frame);
        return true;
      }
      if (type === 'tile_leased' || type === 'tile_done' || type === 'tile_failed') {
        if (!ours.has(d.job)) return true;
        if (type !== 'tile_failed') {
          countTileEvent(seq.tiles, type);
          const f = win.find((x) => x.id === d.job);
          if (f) { countTileEvent(f.tiles, type); strip.update(f); }
          drawHead();
        }
        if (frameView && d.job === frameJob) return frameView.onEvent(type, d);
        return type !== 'tile_failed';  // a failure may fail the frame: refresh
      }
      if (type === 'job_removed') return false;
      return type === 'worker_seen' || type === 'worker_lost' || type === 'worker_changed';
    },
    unmount() {
      mounted = false;
      clearInterval(ticker);
      clearTimeout(reloadTimer);
      strip.destroy();
      if (frameView && frameView.unmount) frameView.unmount();
    },
  };
}
