// Talking to the coordinator: the bearer token (kept in sessionStorage, never in a URL), JSON calls, the preview
// image, the result's download, which endpoints this coordinator has, and the event stream when it exists.
import { SseParser } from './sse.js';
import { ROUTES, JOB_STATES, TILE_STATES } from './protocol.js';

/** The job and tile states, as the coordinator names them (protocol.js, served by the coordinator). */
export { JOB_STATES, TILE_STATES };

/** The path of the coordinator's route `name` (protocol.js) with its {parameters} filled in, in order. */
export function route(name, ...params) {
  let i = 0;
  return ROUTES[name].replace(/\{[^}]+\}/g, () => encodeURIComponent(String(params[i++])));
}

const TOKEN_KEY = 'tessera.clientToken';

export class ApiError extends Error {
  constructor(status, message) {
    super(message);
    this.status = status;
  }
  get isAuth() { return this.status === 401 || this.status === 403; }
}

let authListener = () => {};
/** Called with an ApiError whenever the coordinator refuses the token (401/403). */
export function onAuthError(fn) { authListener = fn; }

export function token() { return sessionStorage.getItem(TOKEN_KEY) || ''; }
export function setToken(t) {
  if (t) sessionStorage.setItem(TOKEN_KEY, t);
  else sessionStorage.removeItem(TOKEN_KEY);
}

function headers(extra) {
  const h = new Headers(extra || {});
  const t = token();
  if (t) h.set('Authorization', 'Bearer ' + t);
  return h;
}

async function errorOf(res) {
  let text = res.statusText || 'error';
  try {
    const body = await res.json();
    if (body && body.error) text = body.error;
  } catch (_) { /* not JSON */ }
  return new ApiError(res.status, text);
}

/** The ApiError of a refused answer, after telling the auth listener when the token was the reason. */
async function refusal(res) {
  const err = await errorOf(res);
  if (err.isAuth) authListener(err);
  return err;
}

/** A JSON call; resolves to the parsed body (null for an empty one), rejects with ApiError. */
export async function call(method, path, body) {
  let res;
  try {
    res = await fetch(path, {
      method,
      headers: headers(body === undefined ? {} : { 'Content-Type': 'application/json' }),
      body: body === undefined ? undefined : JSON.stringify(body),
      cache: 'no-store',
    });
  } catch (e) {
    throw new ApiError(0, 'the coordinator is not reachable (' + e.message + ')');
  }
  if (!res.ok) throw await refusal(res);
  const text = await res.text();
  return text ? JSON.parse(text) : null;
}

/** The preview PNG as a Blob: of the colour, or of the output layer named `layer`. */
export async function previewBlob(jobId, layer = '') {
  const query = layer ? '?layer=' + encodeURIComponent(layer) : '';
  const res = await fetch(route('job_preview', jobId) + query, { headers: headers(), cache: 'no-store' });
  if (!res.ok) throw await errorOf(res);
  return res.blob();
}

/** The preview PNG (of the colour or of `layer`) as an object URL (the caller revokes it). */
export async function previewUrl(jobId, layer = '') {
  return URL.createObjectURL(await previewBlob(jobId, layer));
}

/**
 * Saves a job's result (GET /v1/jobs/{id}/result.exr, fetched with the bearer header, which a plain link cannot
 * send) as a download named `filename`; resolves with the file's size in bytes, rejects with ApiError.
 */
export async function downloadResult(jobId, filename) {
  return download(route('job_result', jobId), filename);
}

/** Saves the file at `path` (fetched with the token) as `filename`; returns its size in bytes. */
export async function download(path, filename) {
  const res = await fetch(path, { headers: headers(), cache: 'no-store' });
  if (!res.ok) throw await refusal(res);
  const blob = await res.blob();
  const url = URL.createObjectURL(blob);
  const a = document.createElement('a');
  a.href = url;
  a.download = filename;
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 60000);  // the browser has taken the bytes long before
  return blob.size;
}

/** Who the coordinator takes this page's token for: {user, role, controls: {pause: any|own|none, ...}}. */
export async function whoami() { return call('GET', route('me')); }

/** What this coordinator offers: {tokens_required, endpoints: {pause, resume, retry, ...}}. */
export async function capabilities() {
  const res = await fetch('/monitor/capabilities.json', { cache: 'no-store' });
  if (!res.ok) throw await errorOf(res);
  return res.json();
}

/**
 * Reads GET /v1/events (Server-Sent Events) with the bearer header (EventSource cannot send one) and calls
 * onEvent({id, type, data}) per event, after onOpen() once the stream is open; with lastEventId, the coordinator
 * first sends what came after it (or a resync event). Resolves when the stream ends; rejects on errors.
 */
export async function streamEvents(onEvent, onOpen, lastEventId, signal) {
  const extra = { Accept: 'text/event-stream' };
  if (lastEventId) extra['Last-Event-ID'] = lastEventId;
  const res = await fetch(route('events'), { headers: headers(extra), signal, cache: 'no-store' });
  if (!res.ok) throw await refusal(res);
  onOpen();
  const parser = new SseParser(onEvent);
  const reader = res.body.pipeThrough(new TextDecoderStream()).getReader();
  for (;;) {
    const { value, done } = await reader.read();
    if (done) return;
    parser.feed(value);
  }
}
