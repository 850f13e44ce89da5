// The monitor's shell: the token dialog, hash routing between the pages, and live updates (the event stream when
// the coordinator has one, polling otherwise).
import * as api from './api.js';
import * as jobsPage from './jobs.js';
import * as jobPage from './job.js';
import * as sequencePage from './sequence.js';
import * as workersPage from './workers.js';

const POLL_MS = 1000;         // without events
const POLL_WITH_EVENTS_MS = 5000;

const state = { caps: null, me: null, view: null, timer: null, busy: false, again: false, eventsLive: false, routeKey: '' };

const $ = (id) => document.getElementById(id);

function showBanner(text) {
  const b = $('banner');
  b.textContent = text || '';
  b.hidden = !text;
}

function setConn(text, cls) {
  const c = $('conn');
  c.textContent = text;
  c.className = 'conn ' + (cls || '');
}

// ---- token ----
function askToken(message) {
  $('token-dialog').hidden = false;
  const err = $('token-error');
  err.textContent = message || '';
  err.hidden = !message;
  $('token-input').value = '';
  $('token-input').focus();
}

function authMessage(e) {
  return e.status === 403
    ? 'The coordinator refused this token (403: ' + e.message + '). Enter the client token or a user\'s token, not a worker\'s.'
    : 'The coordinator refused this token (401: ' + e.message + '). Check the token and try again.';
}

// Who the token stands for: shown in the top bar, and what decides which controls the pages enable.
async function learnWho() {
  state.me = await api.whoami();
  $('whoami').textContent = `${state.me.user} · ${state.me.role}`;
  $('whoami').hidden = false;
}

api.onAuthError((e) => {
  api.setToken('');
  askToken(authMessage(e));
  setConn('token needed', 'bad');
});

$('token-form').addEventListener('submit', async (ev) => {
  ev.preventDefault();
  const t = $('token-input').value.trim();
  if (!t) { askToken('Enter the client token.'); return; }
  api.setToken(t);
  try {
    await api.call('GET', api.route('jobs') + '?limit=1');
    await learnWho();
  } catch (e) {
    if (!e.isAuth) askToken(e.message);
    return;  // onAuthError already reopened the dialog with the reason
  }
  $('token-dialog').hidden = true;
  state.routeKey = '';  // the page again, with the controls this user may use
  mountRoute();
  wakeEvents();
});

$('token-button').addEventListener('click', () => askToken(''));

// ---- pages ----
// The addresses are those format.js's jobHref makes: #/jobs/ID, #/jobs/ID/frames[/N] (a sequence, a frame chosen).
function route() {
  const h = location.hash.replace(/^#\/?/, '');
  const parts = h.split('/').filter(Boolean).map(decodeURIComponent);
  if (parts[0] === 'jobs' && parts[1] && parts[2] === 'frames')
    return { key: 'sequence/' + parts[1], page: sequencePage, arg: parts[1], frame: parts[3], nav: 'jobs' };
  if (parts[0] === 'jobs' && parts[1]) return { key: 'job/' + parts[1], page: jobPage, arg: parts[1], nav: 'jobs' };
  if (parts[0] === 'workers') return { key: 'workers', page: workersPage, nav: 'workers' };
  return { key: 'jobs', page: jobsPage, nav: 'jobs' };
}

function mountRoute() {
  const r = route();
  if (state.view && state.routeKey === r.key) {
    if (state.view.route) state.view.route(r);  // the same page at another place (a sequence's chosen frame)
    return;
  }
  if (state.view && state.view.unmount) state.view.unmount();
  state.routeKey = r.key;
  for (const a of document.querySelectorAll('[data-nav]')) a.classList.toggle('active', a.dataset.nav === r.nav);
  const host = $('view');
  host.replaceChildren();
  state.view = r.page.mount(host, { caps: state.caps, me: state.me, arg: r.arg, frame: r.frame, refresh, banner: showBanner });
  refresh();
}

/** Brings the current page up to date; calls arriving meanwhile coalesce into one more run. */
async function refresh() {
  if (!state.view) return;
  if (!$('token-dialog').hidden) return;
  if (state.busy) { state.again = true; return; }
  state.busy = true;
  try {
    await state.view.refresh();
    showBanner('');
    setConn(state.eventsLive ? 'live (events)' : 'live (polling ' + POLL_MS / 1000 + ' s)', 'ok');
  } catch (e) {
    if (e.isAuth) return;
    if (e.status === 0) { setConn('offline', 'bad'); showBanner('The coordinator is not reachable; retrying…'); }
    else showBanner(e.message);
  } finally {
    state.busy = false;
    if (state.again) { state.again = false; queueMicrotask(refresh); }
  }
}

function schedulePolling() {
  clearInterval(state.timer);
  state.timer = setInterval(refresh, state.eventsLive ? POLL_WITH_EVENTS_MS : POLL_MS);
}

// Every event goes to the page first (the tile map and the job list apply tile and job events at once); what a
// page does not apply itself, and every resync, brings a refresh (a burst of events becomes one). The count of
// events received is exposed as data-events on <body>.
let eventTimer = null, lastEventId = '', eventCount = 0, wakeEvents = () => {};
function onEvent(e) {
  lastEventId = e.id || lastEventId;
  document.body.dataset.events = String(++eventCount);
  let data = null;
  try { data = JSON.parse(e.data); } catch (_) { /* not JSON: refresh below */ }
  const applied = e.type !== 'resync' && data !== null && state.view && state.view.onEvent && state.view.onEvent(e.type, data);
  if (applied) return;
  clearTimeout(eventTimer);
  eventTimer = setTimeout(refresh, 100);
}

async function followEvents() {
  if (!state.caps.endpoints.events) return;
  for (;;) {
    if ($('token-dialog').hidden) {
      try {
        await api.streamEvents(onEvent, () => {
          state.eventsLive = true;
          document.body.dataset.eventsLive = 'true';
          schedulePolling();
          refresh();  // what changed before the stream opened
        }, lastEventId);
      } catch (_) { /* fall back to polling until the stream is back */ }
      state.eventsLive = false;
      document.body.dataset.eventsLive = 'false';
      schedulePolling();
    }
    // Again in 3 s, or as soon as a token is entered.
    await new Promise((r) => { wakeEvents = r; setTimeout(r, 3000); });
  }
}

async function start() {
  try {
    state.caps = await api.capabilities();
  } catch (e) {
    showBanner('Cannot reach the coordinator: ' + e.message);
    setTimeout(start, 2000);
    return;
  }
  $('token-button').hidden = !state.caps.tokens_required;
  if (state.caps.tokens_required && !api.token()) askToken('');
  else {
    try {
      await learnWho();
    } catch (e) {
      if (!e.isAuth) showBanner(e.message);
    }
  }
  window.addEventListener('hashchange', mountRoute);
  mountRoute();
  schedulePolling();
  followEvents();
}

start();
