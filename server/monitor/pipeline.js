// A job's place in a pipeline, as the job page and the sequence page show it: the jobs it waits for and the jobs that
// wait for it (each a link to its page), why it is waiting or blocked, and the outputs of the steps run on its result
// (each file a download, a failed step its log).
import * as api from './api.js';
import { el } from './format.js';

/** A link to a job's page (the page moves on to a sequence's or a frame's own address). */
function jobLink(id) {
  return el('a', { href: '#/jobs/' + encodeURIComponent(id), class: 'mono', 'data-job-link': id, text: id });
}

function links(ids) {
  const out = [];
  ids.forEach((id, i) => { if (i) out.push(', '); out.push(jobLink(id)); });
  return out;
}

export class PipelineView {
  constructor(idPrefix) {
    this.reason = el('div', { class: 'holdbox', id: idPrefix + '-reason', hidden: true });
    this.list = el('dl', { class: 'figures pipeline', id: idPrefix + '-pipeline' });
    this.card = el('div', { class: 'card figures-card', hidden: true }, this.list);
    this.element = el('div', {}, this.reason, this.card);
  }

  update(job) {
    const after = job.after || [];
    const dependents = job.dependents || [];
    const held = job.state === 'waiting' || job.state === 'blocked';
    this.reason.hidden = !(held && job.reason);
    this.reason.textContent = held && job.reason ? (job.state === 'blocked' ? 'Blocked: ' : 'Waiting: ') + job.reason : '';
    const rows = [];
    if (after.length)
      rows.push(['Waits for', [...links(after), job.per_frame ? ' (frame by frame)' : ''], 'pipe-after']);
    if (dependents.length) rows.push(['Then', links(dependents), 'pipe-dependents']);
    for (const o of job.outputs || []) {
      const files = o.files.map((name) => el('button', { type: 'button', class: 'ghost mono', 'data-output': name,
        text: name, onclick: () => api.download(api.route('job_output', job.id, name), name).catch(() => {}) }));
      const shown = o.state === 'done' ? files : [o.state === 'failed' ? 'failed: ' + o.log : o.state];
      rows.push([`Step ${o.step.replace(/_/g, ' ')}`, shown, 'pipe-step-' + o.step]);
    }
    this.card.hidden = rows.length === 0;
    this.list.replaceChildren(...rows.map(([k, v, id]) =>
      el('div', { class: 'fig wide' }, el('dt', { text: k }), el('dd', { id }, ...v))));
  }
}
