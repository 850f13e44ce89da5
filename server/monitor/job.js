// One job: its figures, the live tile map, the partial image, tile details, and the job's controls. The sequence page
// shows its selected frame's job with this view too (ctx.embedded: no crumbs, the frame's number as its title).
import * as api from './api.js';
import { el, badge, duration, clock, jobFigures, progressBar, mrays, shownState, samplingText, arrived,
  clockRuns, jobHref, plural, refusedControl } from './format.js';
import { TileMap, shownTileState, workerColor } from './tilemap.js';
import { JobControls, actor, fetchJob } from './controls.js';
import { PipelineView } from './pipeline.js';

// A worker as the page names it: "name (id)", or the id when it has no name.
function workerText(id, name) { return name ? `${name} (${id})` : id; }

/** The file name a job's result is saved under: its name (or id), reduced to safe characters, with .exr; a frame's
 *  has its number too (name.0042.exr). */
function exrName(job) {
  const base = String(job.name || job.id).replace(/[^A-Za-z0-9._-]+/g, '_').replace(/^[._]+/, '').slice(0, 100);
  const frame = job.sequence ? '.' + String(job.frame).padStart(4, '0') : '';
  return (base || 'tessera-' + job.id) + frame + '.exr';
}

// The tile states the map shows, most advanced first: the coordinator's, a merging tile shown as leased
// (shownTileState), and failed for a pending tile that failed before.
const SHOWN_TILE_STATES = [...api.TILE_STATES.filter((s) => s !== 'merging').reverse(), 'failed'];

export function mount(host, ctx) {
  const id = ctx.arg;
  const ep = ctx.caps.endpoints;
  const path = api.route('job', id);
  let job = null, tiles = [], previewUrl = null, selected = -1;
  // The preview shown is of previewKey (tiles done / state); a change that comes while one is fetched asks again after.
  let previewKey = '', previewBusy = false, previewAgain = false;
  let mounted = true, deleted = false;  // a refresh finishing after the page left or the job was deleted draws nothing
  let spec = null, specAsked = false;  // the job's spec, read once for its sampling settings (they do not change)

  const title = el(ctx.embedded ? 'h2' : 'h1', { id: 'job-title', text: id });
  const stateBadge = el('span', { id: 'job-state' });
  // A frame's view names the frame's own job (for the command line).
  const idNote = ctx.embedded ? el('span', { class: 'sub mono', id: 'frame-job', text: id }) : null;
  const actionMsg = el('p', { class: 'action-msg', id: 'action-msg', role: 'status' });
  const figures = el('dl', { class: 'figures', id: 'job-figures' });
  const errorBox = el('div', { class: 'errorbox', id: 'job-error', hidden: true });
  const pipeline = new PipelineView(ctx.embedded ? 'frame' : 'job');
  const tileCounts = el('div', { class: 'legend', id: 'tile-legend' });
  const detail = el('div', { class: 'tile-detail', id: 'tile-detail' },
    el('p', { class: 'sub', text: 'Click a tile for its worker, failures and log lines.' }));
  const map = new TileMap((i) => { selected = i; drawDetail(); reloadTiles().catch(() => {}); });
  // The tile list as the coordinator has it (events carry states only: attempts, times, rays and logs come from here).
  // How many done tiles' logs the coordinator did not keep (the job's tile logs reached its bound).
  let logsNotKept = 0;
  async function fetchTiles() {
    const body = await api.call('GET', api.route('job_tiles', id));
    tiles = body.tiles || [];
    logsNotKept = body.logs_not_kept || 0;
  }
  async function reloadTiles() {
    await fetchTiles();
    drawTiles();
    drawDetail();
  }
  const img = el('img', { id: 'preview', alt: 'Partial image of the job', hidden: true });
  // Which image the preview shows: the colour, or one of the job's output layers (listed once its spec is read).
  const layerSelect = el('select', { id: 'preview-layer', 'aria-label': 'Layer shown', hidden: true,
    onchange: () => { previewKey = ''; refreshPreview().catch(() => {}); } },
  el('option', { value: '', text: 'Colour' }));
  const imgNote = el('p', { class: 'sub', id: 'preview-note', text: 'The image appears as tiles are done.' });

  // ---- controls ----
  const act = actor(actionMsg, ctx.refresh);
  const controls = new JobControls(ctx, id, act, () => { deleted = true; location.hash = '#/jobs'; });
  // The result as a file, named after the job (a plain link could not carry the token).
  const downloadB = el('button', { type: 'button', class: 'primary', text: 'Download EXR', 'data-action': 'download',
    onclick: async () => {
      actionMsg.className = 'action-msg';
      actionMsg.textContent = 'Download…';
      try {
        const name = exrName(job);
        const bytes = await api.downloadResult(id, name);
        actionMsg.textContent = `Download: ${name} (${(bytes / 1048576).toFixed(1)} MB).`;
      } catch (e) {
        actionMsg.textContent = 'Download failed: ' + e.message;
        actionMsg.className = 'action-msg error';
      }
    } });
  controls.element.prepend(downloadB);
  if (!ctx.embedded) host.append(el('div', { class: 'crumbs' }, el('a', { href: '#/jobs', text: 'Jobs' }), ' / ', el('span', { text: id })));
  host.append(
    el('div', { class: ctx.embedded ? 'page-head frame-head' : 'page-head' },
      el('div', { class: 'title' }, title, stateBadge, idNote), controls.element),
    actionMsg, errorBox, pipeline.element,
    el('div', { class: 'card figures-card' }, figures),
    el('div', { class: 'split' },
      el('section', { class: 'card' },
        el('div', { class: 'card-head' }, el('h2', { text: 'Tiles' }), tileCounts),
        map.grid),
      el('div', { class: 'stack' },
        el('section', { class: 'card' },
          el('div', { class: 'card-head' }, el('h2', { text: 'Image' }), layerSelect,
            el('span', { class: 'sub', id: 'preview-age' })),
          el('div', { class: 'preview-box' }, img), imgNote),
        el('section', { class: 'card' }, detail))));

  // Elapsed time and ETA go on between answers and events while the job's clock runs.
  const ticker = setInterval(() => { if (job && clockRuns(job)) drawHead(); }, 1000);

  function drawHead() {
    title.textContent = job.sequence ? `Frame ${job.frame}` : job.name || job.id;
    stateBadge.replaceChildren(badge(shownState(job)));
    const f = jobFigures(job);
    const t = job.tiles;
    const item = (k, v, idAttr) => [el('dt', { text: k }), el('dd', { text: v, id: idAttr })];
    figures.replaceChildren(
      el('div', { class: 'fig wide' }, el('dt', { text: 'Progress' }), el('dd', {}, progressBar(job))),
      ...[
        item('Done', `${t.done} / ${t.total} tiles (${Math.floor(100 * f.frac)}%)`, 'fig-done'),
        item('Rendering', plural(t.leased, 'tile'), 'fig-leased'),
        item('Elapsed', duration(f.secs)),
        item('ETA', f.eta === null ? '–' : duration(f.eta)),
        item('Mrays/s', mrays(f.mrays)),
        item('Image', `${job.width}×${job.height} · ${job.spp} spp · seed ${job.seed}`),
        item('Sampling', samplingText(spec), 'fig-sampling'),
        // A frame's are its sequence's, shown above it.
        ...(ctx.embedded ? [] : [
          item('Tiles', `${job.tile_size} px`),
          item('Priority', String(job.priority ?? 0), 'fig-priority'),
          item('Owner', job.owner || '–', 'fig-owner'),
          ...(job.require && job.require.length ? [item('Requires', job.require.join(', '), 'fig-require')] : []),
          item('Submitted', clock(job.created_ms))]),
      ].map((pair) => el('div', { class: 'fig' }, pair)));
    errorBox.hidden = !job.error && !job.waiting_for;
    errorBox.textContent = job.error ? 'Failed: ' + job.error : job.waiting_for ? 'Waiting for ' + job.waiting_for + '.' : '';
    pipeline.update(job);
    controls.update(job);
    downloadB.hidden = job.state !== 'done';
  }

  function drawTiles() {
    map.layout(job, tiles);
    map.update(tiles);
    const n = Object.fromEntries(SHOWN_TILE_STATES.map((s) => [s, 0]));
    const workers = new Map();
    for (const t of tiles) {
      const s = shownTileState(t);
      n[s] = (n[s] || 0) + 1;
      if (s === 'leased' && t.worker) workers.set(t.worker, t.worker_name || t.worker);
    }
    tileCounts.replaceChildren(...[
      ...SHOWN_TILE_STATES.map((s) =>
        el('span', { class: 'key', 'data-count': s }, el('i', { class: 'swatch tile', 'data-state': s }), `${s} ${n[s] || 0}`)),
      ...[...workers].map(([w, name]) => {
        const sw = el('i', { class: 'swatch' });
        sw.style.background = workerColor(w);
        return el('span', { class: 'key worker-key', title: w }, sw, name);
      }),
      logsNotKept ? el('span', { class: 'key', id: 'logs-not-kept',
        title: "The job's tile logs reached the coordinator's bound (serve --max-tile-log-bytes)",
        text: `${logsNotKept} tile log${logsNotKept === 1 ? '' : 's'} not kept` }) : null,
    ].filter(Boolean));
    drawDetail();
  }

  function drawDetail() {
    if (selected < 0 || !job) return;
    const t = tiles.find((x) => x.index === selected);
    if (!t) return;
    const [x0, y0, x1, y1] = t.window;
    const rows = [
      ['State', t.state],
      ['Pixels', `[${x0}, ${x1}) × [${y0}, ${y1})`],
      t.state === 'done'
        ? ['Rendered by', t.rendered_by ? workerText(t.rendered_by, t.rendered_by_name) : '–']
        : ['Worker', t.worker ? workerText(t.worker, t.worker_name) : '–'],
      ['Attempts', String(t.attempts ?? 0)],
      ['Render time', t.render_seconds == null ? '–' : `${t.render_seconds.toFixed(2)} s`],
      ['Rays', t.rays ? t.rays.toLocaleString('en-US') : '–'],
    ];
    const failures = t.failures || [];
    // A requeue renders a done tile again, or hands back a failed one; the coordinator answers 409 otherwise.
    const requeue = ep.requeue && !refusedControl(ctx.me, 'requeue', job) && (t.state === 'done' || failures.length) &&
      !['done', 'cancelled'].includes(job.state)
      ? el('button', { type: 'button', id: 'tile-requeue', text: 'Requeue tile', onclick: () => act('Requeue', 'POST', api.route('job_tile_requeue', id, selected)) })
      : null;
    // Log lines a worker sent (with a failure, or with a done tile's upload), or why there are none.
    const logLines = (lines, none) => (lines || []).length
      ? el('pre', { class: 'log', text: lines.join('\n') })
      : el('p', { class: 'sub', text: none });
    detail.replaceChildren(...[
      el('h3', {}, `Tile ${selected}`, requeue),
      el('dl', { class: 'kv' }, rows.map(([k, v]) => [el('dt', { text: k }), el('dd', { text: v })])),
      t.state === 'done'
        ? el('div', { class: 'tile-log' }, el('h4', { text: 'Log' }),
            logLines(t.log, t.log_not_kept ? "Not kept: the job's tile logs reached the coordinator's bound." : 'No log lines sent.'))
        : null,
      failures.length
        ? el('div', { class: 'tile-failures' }, el('h4', { text: 'Failures' }),
            ...failures.map((f) => el('div', { class: 'tile-failure' },
              el('p', { class: 'failure-head', text: `${workerText(f.worker, f.worker_name)}: ${f.error}` }),
              logLines(f.log, 'No log lines sent.'))))
        : el('p', { class: 'sub', text: 'No failures on this tile.' }),
    ].filter(Boolean));
  }

  // Fetches the preview when the job's tiles done or state changed since the one shown. The count is taken before
  // the fetch: the coordinator pastes a tile into the image before it counts it done, so the image holds at least
  // the tiles the label says. A change while a fetch is in flight fetches again once it ends, so the last preview is
  // of the last change.
  async function refreshPreview() {
    if (previewBusy) { previewAgain = true; return; }
    const done = job.tiles.done, total = job.tiles.total;
    const layer = layerSelect.value;
    const key = `${done}/${job.state}/${layer}`;
    if (key === previewKey || done === 0) return;
    previewBusy = true;
    try {
      const url = await api.previewUrl(id, layer);
      await new Promise((resolve) => { img.onload = resolve; img.onerror = resolve; img.src = url; });
      if (previewUrl) URL.revokeObjectURL(previewUrl);
      previewUrl = url;
      previewKey = key;
      img.hidden = false;
      img.dataset.tilesDone = String(done);
      img.dataset.layer = layer;
      imgNote.hidden = true;
      document.getElementById('preview-age').textContent = `${done} of ${total} tiles`;
    } finally {
      previewBusy = false;
    }
    if (previewAgain && mounted) {
      previewAgain = false;
      await refreshPreview();
    }
  }

  return {
    async refresh() {
      if (deleted) return;
      const j = await fetchJob(path, id, host, () => mounted);
      if (!j) return;
      // A sequence has a page of its own, and a frame's job is shown in its sequence's.
      if (!ctx.embedded && (j.frames || j.sequence)) { location.replace(jobHref(j)); return; }
      job = arrived(j);
      if (!specAsked) {
        specAsked = true;
        spec = await api.call('GET', api.route('job_spec', id)).catch(() => null);
        const layers = (spec && Array.isArray(spec.layers)) ? spec.layers : [];
        for (const l of layers) layerSelect.append(el('option', { value: l, text: l }));
        layerSelect.hidden = layers.length === 0;
      }
      drawHead();
      await fetchTiles();
      drawTiles();
      await refreshPreview();
    },
    /** Applies an event of the stream (true: applied, no refresh needed). */
    onEvent(type, d) {
      if (!job) return false;
      if (type === 'job') {
        if (d.id !== id) return true;
        if (d.then && d.then.length) return false;  // its steps' outputs come with the job's own answer, not events
        job = arrived(d);
        drawHead();
        refreshPreview().catch(() => {});
        return true;
      }
      if (type === 'tile_leased' || type === 'tile_done' || type === 'tile_failed') {
        if (d.job !== id) return true;
        const t = tiles.find((x) => x.index === d.tile);
        if (!t) return false;
        const was = t.state;
        if (type === 'tile_leased') {
          Object.assign(t, { state: 'leased', worker: d.worker, worker_name: null, rendered_by: null, attempts: (t.attempts || 0) + 1 });
        } else if (type === 'tile_done') {
          const name = t.worker === d.worker ? t.worker_name : null;
          Object.assign(t, { state: 'done', worker: null, worker_name: null, rendered_by: d.worker, rendered_by_name: name });
          // Tiles the map turned done from events (the browser test reads it).
          map.grid.dataset.eventTilesDone = String(Number(map.grid.dataset.eventTilesDone || 0) + 1);
        } else {
          Object.assign(t, { state: 'pending', worker: null, worker_name: null, rendered_by: null });
          if (Array.isArray(t.failures)) t.failures.push({ worker: d.worker, error: d.error || '' });
          else t.failures = { ...(t.failures || {}), [d.worker]: d.error || '' };
        }
        const c = job.tiles;
        if (was !== t.state) {
          if (was in c) c[was] = Math.max(0, c[was] - 1);
          if (t.state in c) c[t.state] += 1;
        }
        drawHead();
        drawTiles();
        if (d.tile === selected) reloadTiles().catch(() => {});  // the open details show the stored figures
        if (type === 'tile_done') refreshPreview().catch(() => {});
        return true;
      }
      return type === 'worker_seen' || type === 'worker_lost';  // not shown on this page
    },
    unmount() {
      mounted = false;
      clearInterval(ticker);
      if (previewUrl) URL.revokeObjectURL(previewUrl);
    },
  };
}
