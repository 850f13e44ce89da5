// Workers: state, current tile, threads, tiles done and their rate, last seen, tags, blocklists, and drain/undrain
// (for a user whose role may).
import * as api from './api.js';
import { el, badge, ago, mrays, refusedControl } from './format.js';
import { workerColor } from './tilemap.js';

export function mount(host, ctx) {
  const ep = ctx.caps.endpoints;
  const msg = el('p', { class: 'action-msg', id: 'action-msg', role: 'status' });
  const tbody = el('tbody');
  host.append(el('div', { class: 'page-head' }, el('h1', { text: 'Workers' })), msg);
  if (!ep.workers) {
    host.append(el('div', { class: 'card notice', id: 'workers-unavailable' },
      el('p', { text: 'This coordinator does not list its workers (it has no worker list endpoint yet).' }),
      el('p', { class: 'sub', text: 'Each job page still shows which worker holds each tile.' })));
    return { async refresh() {} };
  }
  host.append(el('div', { class: 'card' }, el('table', { class: 'workers', id: 'workers-table' },
    el('thead', {}, el('tr', {}, ['Worker', 'State', 'Current tile', 'Threads', 'Tiles done', 'Mrays/s', 'Last seen', 'Tags', 'Blocklisted for', '']
      .map((h) => el('th', { text: h })))),
    tbody)));

  async function act(label, url) {
    msg.textContent = label + '…';
    msg.className = 'action-msg';
    try {
      await api.call('POST', url);
      msg.textContent = label + ': done.';
    } catch (e) {
      msg.textContent = label + ' failed: ' + e.message;
      msg.className = 'action-msg error';
    }
    ctx.refresh();
  }

  function row(w) {
    const id = w.id;
    const draining = w.state === 'draining' || w.draining === true;
    const refused = refusedControl(ctx.me, 'drain');
    const button = !ep.drain
      ? el('button', { type: 'button', text: 'Drain', disabled: true, title: 'This coordinator has no drain endpoint yet.' })
      : refused
        ? el('button', { type: 'button', text: draining ? 'Undrain' : 'Drain', disabled: true, title: refused })
      : draining
        ? el('button', { type: 'button', text: 'Undrain', 'data-action': 'undrain', onclick: () => act('Undrain ' + (w.name || id), api.route('worker_undrain', id)) })
        : el('button', { type: 'button', text: 'Drain', 'data-action': 'drain', disabled: w.state === 'offline',
            onclick: () => act('Drain ' + (w.name || id), api.route('worker_drain', id)) });
    const sw = el('i', { class: 'swatch' });
    sw.style.background = workerColor(id);
    const job = w.job || w.current_job;
    const tile = w.tile ?? w.current_tile;
    const blocked = w.blocklisted_for || [];
    return el('tr', { 'data-worker': id, 'data-name': w.name || '' },
      el('td', {}, sw, ' ', el('span', { class: 'job-name', text: w.name || id }), el('div', { class: 'sub', text: id })),
      el('td', {}, badge(w.state || 'unknown')),
      el('td', {}, job ? el('a', { href: '#/jobs/' + encodeURIComponent(job), text: `${job} #${tile ?? '?'}` }) : '–'),
      el('td', { class: 'num', text: w.threads ? String(w.threads) : '–' }),
      el('td', { class: 'num', text: String(w.tiles_done ?? '–') }),
      // Its rate over the tiles it rendered: their rays over their render times (lease grant to acceptance).
      el('td', { class: 'num rate', text: mrays(w.rays && w.render_seconds > 0 ? w.rays / w.render_seconds / 1e6 : null) }),
      el('td', { text: ago(w.last_seen_ms) }),
      el('td', { class: 'tags' }, ...(w.tags && w.tags.length ? w.tags.map((t) => el('span', { class: 'tag', text: t })) : ['–'])),
      el('td', { class: 'sub', text: blocked.length ? blocked.join(', ') : '–' }),
      el('td', {}, button));
  }

  return {
    async refresh() {
      const body = await api.call('GET', api.route('workers'));
      const list = Array.isArray(body) ? body : body.workers || [];
      tbody.replaceChildren(...list.map(row));
      if (!list.length) tbody.append(el('tr', {}, el('td', { colspan: '10', class: 'empty', text: 'No workers registered.' })));
    },
  };
}
