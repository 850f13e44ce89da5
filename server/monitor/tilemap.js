// The tile map: one cell per tile in the image's shape, coloured by state (leased tiles by their worker).
import { el } from './format.js';

// Hues far from done (green) and failed (red).
const WORKER_HUES = [38, 205, 275, 320, 185, 55, 235, 300, 20, 250];

/** A stable colour per worker id. */
export function workerColor(id) {
  let h = 0;
  for (const c of String(id)) h = (h * 31 + c.charCodeAt(0)) >>> 0;
  return `hsl(${WORKER_HUES[h % WORKER_HUES.length]} 75% 62%)`;
}

/** The state a tile is drawn in: its own ('merging' is drawn as leased), or 'failed' for a pending tile that has
 *  failed on some worker. */
export function shownTileState(t) {
  if (t.state === 'merging') return 'leased';
  return t.state === 'pending' && (t.failures || []).length ? 'failed' : t.state;
}

export class TileMap {
  constructor(onSelect) {
    this.grid = el('div', { class: 'tilemap', id: 'tilemap', role: 'grid', 'aria-label': 'Tiles' });
    this.onSelect = onSelect;
    this.cells = [];
    this.shape = '';
    this.selected = -1;
  }

  /** Lays the grid out from the tiles' windows (the list from GET of the job's tiles, in tile order). */
  layout(job, tiles) {
    if (!tiles.length) return;
    const shape = `${job.width}x${job.height}/${tiles.length}/${tiles[0].window}`;
    if (shape === this.shape) return;
    this.shape = shape;
    const firstRow = tiles.filter((t) => t.window[1] === tiles[0].window[1]);
    const firstCol = tiles.filter((t) => t.window[0] === tiles[0].window[0]);
    const cols = firstRow.length, rows = firstCol.length;
    this.grid.style.gridTemplateColumns = firstRow.map((t) => `${t.window[2] - t.window[0]}fr`).join(' ');
    this.grid.style.gridTemplateRows = firstCol.map((t) => `${t.window[3] - t.window[1]}fr`).join(' ');
    this.grid.style.aspectRatio = `${job.width} / ${job.height}`;
    this.grid.style.setProperty('--aspect', String(job.width / job.height));
    this.grid.classList.toggle('dense', cols * rows > 1500);
    this.cells = [];
    const frag = document.createDocumentFragment();
    for (let i = 0; i < cols * rows; i++) {
      const c = el('div', { class: 'tile', role: 'gridcell', 'data-index': String(i), 'data-state': 'pending', onclick: () => this.select(i) });
      this.cells.push(c);
      frag.append(c);
    }
    this.grid.replaceChildren(frag);
  }

  select(i) {
    if (this.cells[this.selected]) this.cells[this.selected].classList.remove('selected');
    this.selected = i;
    if (this.cells[i]) this.cells[i].classList.add('selected');
    this.onSelect(i);
  }

  /** Draws tile states; `tiles` is the list from GET /v1/jobs/{id}/tiles. */
  update(tiles) {
    for (const t of tiles) {
      const c = this.cells[t.index];
      if (!c) continue;
      const s = shownTileState(t);
      const worker = s === 'leased' ? (t.worker_name || t.worker || '') : '';
      if (c.dataset.state !== s) c.dataset.state = s;
      if ((c.dataset.worker || '') !== (t.worker || '')) {
        c.dataset.worker = t.worker || '';
        c.style.setProperty('--worker', t.worker && s === 'leased' ? workerColor(t.worker) : '');
      }
      c.title = `Tile ${t.index}: ${s}${worker ? ' on ' + worker : ''}`;
    }
  }
}
