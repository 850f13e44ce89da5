// A job's controls, as the job page and the sequence page show them: pause, resume, retry, cancel, priority and
// delete, each shown in the states it applies to and enabled when the coordinator has its endpoint
// (capabilities.json) and the user may use it on this job (GET /v1/me: its role, and whether the job is its own). A sequence's act on all its frames; a frame's job has only retry, which retries that frame of
// its sequence (the coordinator refuses the others on a frame: they belong to the sequence).
import * as api from './api.js';
import { el, isPaused, FINAL, refusedControl } from './format.js';

/** A button that needs a second click within 4 s (for cancel and delete). */
/**
 * The job at `path`, or null once `host` says there is no such job (404) or the page was left meanwhile
 * (`isMounted()` false); other errors are thrown.
 */
export async function fetchJob(path, id, host, isMounted) {
  try {
    return await api.call('GET', path);
  } catch (e) {
    if (!isMounted()) return null;
    if (e.status === 404) {
      host.replaceChildren(el('div', { class: 'card empty' }, `No job ${id} on this coordinator. `,
        el('a', { href: '#/jobs', text: 'Back to the jobs' })));
      return null;
    }
    throw e;
  }
}

export function confirmButton(label, confirmLabel, action, cls) {
  let armed = null;
  const b = el('button', { type: 'button', class: cls || '', text: label });
  b.addEventListener('click', () => {
    if (!armed) {
      b.textContent = confirmLabel;
      b.classList.add('armed');
      armed = setTimeout(() => { armed = null; b.textContent = label; b.classList.remove('armed'); }, 4000);
      return;
    }
    clearTimeout(armed);
    armed = null;
    b.textContent = label;
    b.classList.remove('armed');
    action();
  });
  return b;
}

/**
 * Calls of the coordinator that tell how they went in `msg` (an .action-msg element) and then bring the page up to
 * date: act(label, method, url, body, after) runs `after` once the call succeeded.
 */
export function actor(msg, refresh) {
  return async function act(label, method, url, body, after) {
    msg.textContent = label + '…';
    msg.className = 'action-msg';
    try {
      await api.call(method, url, body);
      msg.textContent = label + ': done.';
      if (after) after();
    } catch (e) {
      msg.textContent = label + ' failed: ' + e.message;
      msg.className = 'action-msg error';
    }
    refresh();
  };
}

const missing = (what) => `This coordinator has no ${what} endpoint yet.`;

/** The controls of job `id`; `element` holds them, update(job) shows those that apply to its status. */
export class JobControls {
  /** ctx: the page's (caps, refresh); act: from actor(); onDeleted: called once a purge succeeded. */
  constructor(ctx, id, act, onDeleted) {
    const ep = ctx.caps.endpoints;
    const path = api.route('job', id);
    this.job = null;
    this.me = ctx.me;
    this.ep = ep;
    const btn = (label, name, enabledBy, onClick, cls) => {
      const b = el('button', { type: 'button', text: label, 'data-action': name, class: cls || '', onclick: onClick });
      b.dataset.supported = enabledBy ? 'yes' : 'no';
      if (!enabledBy) { b.disabled = true; b.title = missing(label.toLowerCase()); }
      return b;
    };
    this.pauseB = btn('Pause', 'pause', ep.pause, () => act('Pause', 'POST', api.route('job_pause', id)));
    this.resumeB = btn('Resume', 'resume', ep.resume, () => act('Resume', 'POST', api.route('job_resume', id)));
    // A frame is retried through its sequence, naming it; a sequence retries every failed or cancelled frame.
    this.retryB = btn('Retry', 'retry', ep.retry, () => {
      const j = this.job;
      if (j && j.sequence) act(`Retry frame ${j.frame}`, 'POST', api.route('job_retry', j.sequence), { frames: [j.frame] });
      else act('Retry', 'POST', api.route('job_retry', id));
    }, 'primary');
    this.cancelB = confirmButton('Cancel', 'Click to confirm', () => act('Cancel', 'DELETE', path), 'danger');
    this.cancelB.dataset.action = 'cancel';
    this.cancelB.dataset.supported = 'yes';
    this.deleteB = confirmButton('Delete', 'Click to delete for good',
      () => act('Delete', 'DELETE', path + '?purge=true', undefined, onDeleted), 'danger');
    this.deleteB.dataset.action = 'delete';
    this.deleteB.dataset.supported = ep.purge ? 'yes' : 'no';
    if (!ep.purge) { this.deleteB.disabled = true; this.deleteB.title = missing('purge (DELETE ?purge=true)'); }
    this.prioInput = el('input', { type: 'number', class: 'priority-input', step: '1', 'aria-label': 'Priority' });
    const prioB = btn('Set priority', 'priority', ep.priority,
      () => act('Priority', 'PATCH', path, { priority: Number(this.prioInput.value) }));
    if (!ep.priority) { this.prioInput.disabled = true; this.prioInput.title = missing('priority (PATCH)'); }
    this.prio = el('span', { class: 'prio' }, this.prioInput, prioB);
    this.element = el('div', { class: 'actions' },
      this.pauseB, this.resumeB, this.retryB, this.cancelB, this.prio, this.deleteB);
  }

  update(job) {
    this.job = job;
    // What the user may do to this job: a control its role or the job's owner rules out is shown disabled, saying why.
    for (const [b, cap] of [[this.pauseB, 'pause'], [this.resumeB, 'resume'], [this.retryB, 'retry'],
      [this.cancelB, 'purge'], [this.deleteB, 'purge'], [this.prioInput, 'priority'], [this.prio.lastChild, 'priority']]) {
      if (!this.ep[cap]) continue;  // disabled already: the coordinator has no such endpoint
      const why = refusedControl(this.me, cap, job.sequence ? { owner: job.owner } : job);
      b.disabled = Boolean(why);
      b.title = why;
    }
    const paused = isPaused(job), final = FINAL.includes(job.state), frame = Boolean(job.sequence);
    const f = job.frames;
    this.pauseB.hidden = paused || final || frame;
    this.resumeB.hidden = !paused || frame;
    // A sequence can retry its failed and cancelled frames while others still render.
    const retryable = f ? f.failed + f.cancelled > 0 : job.state === 'failed' || job.state === 'cancelled';
    this.retryB.hidden = !retryable;
    this.retryB.textContent = frame ? 'Retry frame' : f ? `Retry ${f.failed + f.cancelled} frame${f.failed + f.cancelled === 1 ? '' : 's'}` : 'Retry';
    this.retryB.title = frame ? `Render frame ${job.frame} of ${job.sequence} again (its tiles done are kept)`
      : f ? 'Render the failed and cancelled frames again' : '';
    this.cancelB.hidden = final || frame;
    this.prio.hidden = frame;
    this.deleteB.hidden = !final || frame;
    if (document.activeElement !== this.prioInput) this.prioInput.value = String(job.priority ?? 0);
  }
}
