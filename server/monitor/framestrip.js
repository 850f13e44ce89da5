// The frame strip of the sequence page: one cell per frame of the window shown (a page of GET /v1/jobs/{id}/frames),
// a done frame as a thumbnail of its job's preview, the others in their state's colour with their tiles' progress.
// Thumbnails are fetched only for cells scrolled into sight, a few at a time, and kept small in a cache of the tab.
import * as api from './api.js';
import { el, shownState } from './format.js';

const THUMB_H = 66;       // the height of a thumbnail on the page (CSS pixels)
const THUMB_PX = 256;     // the long side of a kept thumbnail (shown at about half that, sharp on a 2x screen)
const CACHE_LIMIT = 600;  // thumbnails kept, least recently used forgotten first (a few tens of kB each)
const LOADS_AT_ONCE = 3;  // preview requests in flight

// A frame job's id -> the object URL of its thumbnail, least recently used first (a Map keeps insertion order).
const cache = new Map();

function cached(jobId) {
  const url = cache.get(jobId);
  if (url) { cache.delete(jobId); cache.set(jobId, url); }
  return url;
}

function keep(jobId, url) {
  forget(jobId);
  cache.set(jobId, url);
  while (cache.size > CACHE_LIMIT) forget(cache.keys().next().value);
}

function forget(jobId) {
  const url = cache.get(jobId);
  if (url) URL.revokeObjectURL(url);
  cache.delete(jobId);
}

/** A done frame's preview, scaled down to THUMB_PX on its long side, as an object URL. */
async function thumbnail(jobId) {
  const blob = await api.previewBlob(jobId);
  const bitmap = await createImageBitmap(blob);
  const scale = Math.min(1, THUMB_PX / Math.max(bitmap.width, bitmap.height));
  if (scale === 1) { bitmap.close(); return URL.createObjectURL(blob); }
  const canvas = el('canvas', { width: Math.round(bitmap.width * scale), height: Math.round(bitmap.height * scale) });
  const g = canvas.getContext('2d');
  g.imageSmoothingQuality = 'high';
  g.drawImage(bitmap, 0, 0, canvas.width, canvas.height);
  bitmap.close();
  const small = await new Promise((resolve) => canvas.toBlob(resolve, 'image/png'));
  return URL.createObjectURL(small || blob);
}

export class FrameStrip {
  /** onSelect(frameJob) is called when a cell is clicked. */
  constructor(onSelect) {
    this.element = el('div', { class: 'frame-strip', id: 'frame-strip', role: 'listbox', 'aria-label': 'Frames' });
    this.onSelect = onSelect;
    this.cells = new Map();  // frame number -> cell (a <button> whose .job is the frame's job status)
    this.selected = null;
    this.queue = [];         // frame numbers whose thumbnail is wanted, in the order they came into sight
    this.loading = new Set();  // frame job ids being fetched
    this.fetched = 0;        // thumbnails fetched by this strip (data-thumbs-fetched; the browser test reads it)
    this.observer = new IntersectionObserver((entries) => {
      for (const e of entries) {
        e.target.inSight = e.isIntersecting;
        if (e.isIntersecting) this.want(e.target);
      }
    }, { root: this.element, rootMargin: '0px 160px' });
  }

  /** Shows `frames` (a window of the sequence's frames, in number order), keeping the cells of frames shown before. */
  show(frames, width, height) {
    // Thumbnails are THUMB_H CSS pixels high and as wide as the sequence's (first frame's) shape, within bounds.
    const aspect = width && height ? width / height : 16 / 9;
    this.element.style.setProperty('--thumb-w', Math.round(Math.min(2.4, Math.max(1, aspect)) * THUMB_H) + 'px');
    const next = new Map();
    for (const f of frames) {
      let c = this.cells.get(f.frame);
      if (!c || c.job.id !== f.id) {
        c = el('button', { type: 'button', class: 'frame-cell', role: 'option', 'data-frame': String(f.frame),
          onclick: () => this.onSelect(c.job) },
        el('div', { class: 'frame-thumb' }, el('span', { class: 'frame-note' }),
          el('div', { class: 'frame-progress' }, el('i'))),
        el('span', { class: 'frame-num' }, el('i', { class: 'dot' }), String(f.frame)));
        c.inSight = false;
        this.observer.observe(c);
      }
      next.set(f.frame, c);
      this.draw(c, f);
    }
    for (const [n, c] of this.cells) if (next.get(n) !== c) this.observer.unobserve(c);
    const same = next.size === this.cells.size && [...next].every(([n, c]) => this.cells.get(n) === c);
    this.cells = next;
    if (!same) this.element.replaceChildren(...next.values());  // unchanged cells stay put: the scroll stays
    this.select(this.selected, false);
  }

  /** A frame's job changed (an event or a reload): redraws its cell when it is shown. */
  update(frameJob) {
    const c = this.cells.get(frameJob.frame);
    if (c && c.job.id === frameJob.id) this.draw(c, frameJob);
  }

  /** A frame's result was written (frame_done): its cell shows it done, with its thumbnail (fetched once). */
  refreshThumb(frame) {
    const c = this.cells.get(frame);
    if (!c) return;
    if (c.dataset.state !== 'done') {
      const t = c.job.tiles || {};
      this.draw(c, { ...c.job, state: 'done', tiles: { ...t, done: t.total, leased: 0, pending: 0 } });
    }
    this.want(c);
  }

  /** Marks frame `n`'s cell selected (scrolled into the middle of the strip when `scroll`). */
  select(n, scroll = true) {
    this.selected = n;
    for (const [k, c] of this.cells) {
      c.classList.toggle('selected', k === n);
      c.setAttribute('aria-selected', k === n ? 'true' : 'false');
    }
    const c = this.cells.get(n);
    if (c && scroll) this.element.scrollLeft = c.offsetLeft - (this.element.clientWidth - c.offsetWidth) / 2;
  }

  destroy() { this.observer.disconnect(); this.queue = []; }

  draw(c, f) {
    c.job = f;
    const state = shownState(f);
    const t = f.tiles || { total: 0, done: 0 };
    const pct = t.total ? 100 * t.done / t.total : 0;
    c.dataset.state = state;
    c.dataset.job = f.id;
    // The job states' colours (.state-*, as the badges have them) tint the thumbnail's place and the number's dot.
    c.querySelector('.frame-thumb').className = 'frame-thumb state-' + state;
    c.querySelector('.dot').className = 'dot state-' + state;
    c.title = `Frame ${f.frame}: ${state}` + (state === 'done' ? '' : `, ${t.done} of ${t.total} tiles`) +
      (f.error ? ` (${f.error})` : '');
    c.querySelector('.frame-note').textContent = state === 'done' ? '' : state === 'running' ? `${pct.toFixed(0)}%` : state;
    c.querySelector('.frame-progress i').style.width = pct.toFixed(1) + '%';
    if (state === 'done') {
      this.want(c);
    } else {  // not done (again): a thumbnail shown or kept is not of its image
      forget(f.id);
      if (c.dataset.thumb) {
        c.querySelector('img')?.remove();
        delete c.dataset.thumb;
      }
    }
  }

  /** Shows a done frame's thumbnail: at once from the cache, else fetched once its cell is in sight. */
  want(c) {
    if (c.dataset.state !== 'done' || c.dataset.thumb) return;
    const url = cached(c.job.id);
    if (url) { this.put(c, url); return; }
    if (!c.inSight || this.loading.has(c.job.id) || this.queue.includes(c.job.frame)) return;
    this.queue.push(c.job.frame);
    this.pump();
  }

  pump() {
    while (this.loading.size < LOADS_AT_ONCE && this.queue.length) {
      const c = this.cells.get(this.queue.shift());
      if (!c || !c.inSight || c.dataset.state !== 'done' || c.dataset.thumb) continue;
      const id = c.job.id;
      this.loading.add(id);
      this.fetched += 1;
      this.element.dataset.thumbsFetched = String(this.fetched);
      thumbnail(id).then((url) => {
        keep(id, url);
        const now = this.cells.get(c.job.frame);
        if (now && now.job.id === id && now.dataset.state === 'done') this.put(now, url);
      }, () => { /* shown in its state's colour; tried again when it next comes into sight */ })
        .finally(() => { this.loading.delete(id); this.pump(); });
    }
  }

  put(c, url) {
    const thumb = c.querySelector('.frame-thumb');
    let img = thumb.querySelector('img');
    if (!img) { img = el('img', { alt: `Frame ${c.job.frame}` }); thumb.prepend(img); }
    img.src = url;
    c.dataset.thumb = 'shown';
  }
}
