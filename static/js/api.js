// The page's client of the geomint HTTP API: the two catalogues, a system definition checked and
// stored (POST /api/v1/systems), the NDJSON simulation stream
// (POST /api/v1/simulate with Accept: application/x-ndjson) and its one-document answer, the run
// as a Rerun recording (?format=rrd, POST /api/v1/recordings), the stored recordings (list, entry,
// samples read back, upload of an .rrd file, delete), the stability analysis
// (POST /api/v1/stability, /api/v1/stability/point) and the studies (POST
// /api/v1/studies/work-precision, /convergence and /energy-map, the map also as a recording, and
// /basins).
// Every request carries the header's bearer token, if the user gave one (token.js). Errors in
// the service's shape, {"error": {"code", "message", "field", "position"}}, become
// ApiError objects that keep the field path and, for an expression, the character position.

import { withToken } from './token.js';

/** An error answered by the API (or a stream's `error` line). */
export class ApiError extends Error {
  /**
   * @param {{code?: string, message?: string, field?: string|null, position?: number}} detail
   * @param {number} [status] HTTP status, when the error came as a response
   * @param {number|null} [method] index of the method concerned (stream errors)
   */
  constructor(detail, status = 0, method = null) {
    super(detail?.message || 'the server answered with an error');
    this.name = 'ApiError';
    this.code = detail?.code || 'unknown';
    this.field = detail?.field ?? null;
    /** For an expression's error: the 0-based index of the character (code point) it is at. */
    this.position = Number.isInteger(detail?.position) ? detail.position : null;
    this.status = status;
    this.method = method;
  }
}

/** Reads an error response body, which should be the service's JSON error shape. */
async function errorFrom(response) {
  let detail = null;
  try {
    detail = (await response.json())?.error ?? null;
  } catch {
    // Not JSON (a proxy in between, say): fall back to the status line.
  }
  if (!detail) {
    detail = { code: 'http_' + response.status, message: `HTTP ${response.status} ${response.statusText}` };
  }
  if (response.status === 503) {
    const retry = response.headers.get('retry-after');
    if (retry) detail = { ...detail, message: `${detail.message} (retry in ${retry} s)` };
  }
  return new ApiError(detail, response.status);
}

/** GETs a JSON document of the API. */
async function getJson(path) {
  const response = await fetch(path, { headers: withToken({ accept: 'application/json' }) });
  if (!response.ok) throw await errorFrom(response);
  return response.json();
}

/** The server's OpenAPI document, fetched once (a promise; null when it cannot be had). */
let openApi = null;

/**
 * Whether the server's request schema `schema` has the property `field` (a server older than
 * the page refuses fields it does not know).
 */
export async function serverOffers(schema, field) {
  openApi ??= getJson('api/v1/openapi.json').catch(() => null);
  const doc = await openApi;
  return Boolean(doc?.components?.schemas?.[schema]?.properties?.[field]);
}

/** The system and method catalogues. */
export async function catalogues() {
  const [systems, methods] = await Promise.all([getJson('api/v1/systems'), getJson('api/v1/methods')]);
  return { systems, methods };
}

/**
 * Checks a system definition and stores it (POST /api/v1/systems). Resolves to the stored entry
 * (its catalogue fields, `definition`, `facts`, `created_unix_ms`) with `created`: whether it was
 * new (201) rather than stored already (200). Rejects with an ApiError naming the field (and, for
 * an expression, the character) of a problem.
 */
export async function storeSystem(definition, signal) {
  const response = await post('api/v1/systems', definition, { signal });
  return { ...(await response.json()), created: response.status === 201 };
}

/** A stored system definition's entry (GET /api/v1/systems/{id}): its catalogue fields, `definition`, `facts`. */
export async function getSystem(id) {
  return getJson(`api/v1/systems/${encodeURIComponent(id)}`);
}

/**
 * Runs a simulation as an NDJSON stream, calling `onLine` with every parsed line in order.
 * Resolves once the `end` line arrived; rejects with an ApiError for error answers, with an
 * Error when the stream is cut short, and with the AbortError of `signal` when cancelled.
 *
 * @param {object} request the body of POST /api/v1/simulate
 * @param {(line: object) => void} onLine
 * @param {AbortSignal} signal
 */
export async function simulateStream(request, onLine, signal) {
  return ndjsonStream('api/v1/simulate', request, onLine, signal);
}

/**
 * POSTs `body` to `path` asking for NDJSON, and calls `onLine` with each line as it arrives.
 * Rejects with an ApiError when the server refuses the request, and when the stream ends without
 * its `end` line.
 */
async function ndjsonStream(path, body, onLine, signal) {
  const response = await fetch(path, {
    method: 'POST',
    headers: withToken({ 'content-type': 'application/json', accept: 'application/x-ndjson' }),
    body: JSON.stringify(body),
    signal,
  });
  if (!response.ok) throw await errorFrom(response);
  let ended = false;
  await readNdjson(response, (line) => {
    if (line.type === 'end') ended = true;
    onLine(line);
  });
  if (!ended) throw new Error('the stream ended before its last line: the server stopped early');
}

/** Calls `onLine` with each line of an NDJSON `response`, parsed, as it arrives. */
async function readNdjson(response, onLine) {
  const reader = response.body.getReader();
  const decoder = new TextDecoder();
  let pending = '';
  const handle = (text) => {
    if (text.trim()) onLine(JSON.parse(text));
  };
  for (;;) {
    const { value, done } = await reader.read();
    if (done) break;
    pending += decoder.decode(value, { stream: true });
    // Handle every complete line, then keep only the unfinished tail (one copy per read).
    let start = 0;
    let newline;
    while ((newline = pending.indexOf('\n', start)) >= 0) {
      handle(pending.slice(start, newline));
      start = newline + 1;
    }
    pending = pending.slice(start);
  }
  pending += decoder.decode();
  handle(pending);
}

/**
 * A work–precision study (POST /api/v1/studies/work-precision) streamed as NDJSON: `reference`,
 * one `point` per finished setting, `result`, `end` (or `error`).
 */
export async function workPrecisionStream(body, onLine, signal) {
  return ndjsonStream('api/v1/studies/work-precision', body, onLine, signal);
}

/**
 * A convergence study (POST /api/v1/studies/convergence) streamed as NDJSON: `reference`, one
 * `point` per finished setting, `result`, `end` (or `error`).
 */
export async function convergenceStream(body, onLine, signal) {
  return ndjsonStream('api/v1/studies/convergence', body, onLine, signal);
}

/** The study `body` as a Rerun recording (.rrd bytes). */
export async function workPrecisionRrd(body, signal) {
  const response = await post('api/v1/studies/work-precision?format=rrd', body, { accept: 'application/octet-stream', signal });
  return response.blob();
}

/** POSTs `body` as JSON to `path`; resolves with the response when it is OK. */
async function post(path, body, { accept = 'application/json', signal } = {}) {
  const response = await fetch(path, {
    method: 'POST',
    headers: withToken({ 'content-type': 'application/json', accept }),
    body: JSON.stringify(body),
    signal,
  });
  if (!response.ok) throw await errorFrom(response);
  return response;
}

/** A basin map (POST /api/v1/studies/basins) as NDJSON lines: progress, then the result. */
export async function basinsStream(body, onLine, signal) {
  return ndjsonStream('api/v1/studies/basins', body, onLine, signal);
}

/** The server's ready-made basin maps: [{id, title, request}]. */
export async function basinsPresets() {
  return getJson('api/v1/studies/basins/presets');
}

/** The simulation of `request` as one JSON document (the whole run at once). */
export async function simulateJson(request, signal) {
  return (await post('api/v1/simulate', request, { signal })).json();
}

/**
 * Which points of a section's plane can start an orbit at the request's energy
 * (POST /api/v1/simulate/allowed-region): the body is an orbit's request with `plane`.
 */
export async function allowedRegion(body, signal) {
  return (await post('api/v1/simulate/allowed-region', body, { signal })).json();
}

/**
 * An energy-error map (POST /api/v1/studies/energy-map) streamed as NDJSON: `progress` lines,
 * then `result` (the map document) and `end`, or an `error` line.
 */
export async function energyMapStream(body, onLine, signal) {
  return ndjsonStream('api/v1/studies/energy-map', body, onLine, signal);
}

/** The energy-error map of `body` as a Rerun recording (.rrd bytes), computed afresh. */
export async function energyMapRrd(body, signal) {
  const response = await post('api/v1/studies/energy-map?format=rrd', body, { accept: 'application/octet-stream', signal });
  return response.blob();
}

/** A sweep (POST /api/v1/studies/sweep) as NDJSON lines: progress, then the result. */
export async function sweepStream(body, onLine, signal) {
  return ndjsonStream('api/v1/studies/sweep', body, onLine, signal);
}

/** The sweep of `body` as a Rerun recording (.rrd bytes), computed afresh. */
export async function sweepRrd(body, signal) {
  const response = await post('api/v1/studies/sweep?format=rrd', body, { accept: 'application/octet-stream', signal });
  return response.blob();
}

/** The server's ready-made sweeps: [{id, title, request}]. */
export async function sweepPresets() {
  return getJson('api/v1/studies/sweep/presets');
}

/** The simulation of `request` as a Rerun recording (.rrd bytes), computed afresh. */
export async function simulateRrd(request, signal) {
  const response = await post('api/v1/simulate?format=rrd', request, { accept: 'application/octet-stream', signal });
  return response.blob();
}

/**
 * Runs `request` and stores its Rerun recording on the server.
 * @returns {Promise<{id: string, url: string, bytes: number}>} `url` is an absolute path
 */
export async function createRecording(request, signal) {
  return (await post('api/v1/recordings', request, { signal })).json();
}

/** The stability maps of `body` as a Rerun recording (.rrd bytes). */
export async function stabilityRrd(body, signal) {
  const response = await post('api/v1/stability?format=rrd', body, { accept: 'application/octet-stream', signal });
  return response.blob();
}

/** Stability maps over a (γ, h) grid: the body and answer of POST /api/v1/stability. */
export async function stabilityMaps(body, signal) {
  return (await post('api/v1/stability', body, { signal })).json();
}

/** The stability analysis of one method at one (ω, γ, h): POST /api/v1/stability/point. */
export async function stabilityPoint(body, signal) {
  return (await post('api/v1/stability/point', body, { signal })).json();
}

/** The stored recordings, newest first (GET /api/v1/recordings). */
export async function listRecordings(signal) {
  const response = await fetch('api/v1/recordings', { headers: withToken({ accept: 'application/json' }), signal });
  if (!response.ok) throw await errorFrom(response);
  return response.json();
}

/** One stored recording's entry; rejects with an ApiError of status 404 when there is none. */
export async function getRecording(id) {
  return getJson(`api/v1/recordings/${encodeURIComponent(id)}`);
}

/** A stored simulation recording's samples, read back from its .rrd by the server. */
export async function recordingSamples(id, signal) {
  const response = await fetch(`api/v1/recordings/${encodeURIComponent(id)}/samples`, {
    headers: withToken({ accept: 'application/json' }), signal,
  });
  if (!response.ok) throw await errorFrom(response);
  return response.json();
}

/** Deletes a stored recording; resolves to false when it was already gone (404). */
export async function deleteRecording(id) {
  const response = await fetch(`api/v1/recordings/${encodeURIComponent(id)}`, {
    method: 'DELETE', headers: withToken(),
  });
  if (response.status === 404) return false;
  if (!response.ok) throw await errorFrom(response);
  return true;
}

/**
 * Uploads an .rrd file (a File or Blob, sent as it is) to the library.
 * @returns {Promise<{id: string, url: string, bytes: number}>}
 */
export async function uploadRecording(file, signal) {
  const response = await fetch('api/v1/recordings', {
    method: 'POST',
    headers: withToken({ 'content-type': 'application/octet-stream', accept: 'application/json' }),
    body: file,
    signal,
  });
  if (!response.ok) throw await errorFrom(response);
  return response.json();
}

/**
 * Submits a study as a job (POST /api/v1/jobs): `study` is its route's name (`sweep`, `basins`,
 * `energy-map`, `work-precision`, `convergence`, `stability`), `request` the body that route
 * takes. Resolves to the job's status; an error names the request's field as the route would
 * (the API's `request.` prefix taken off).
 */
export async function submitJob(study, request, signal) {
  try {
    return await (await post('api/v1/jobs', { study, request }, { signal })).json();
  } catch (error) {
    if (error instanceof ApiError && error.field?.startsWith('request')) {
      error.field = error.field.replace(/^request\.?/, '') || null;
    }
    throw error;
  }
}

/** The caller's jobs (GET /api/v1/jobs), oldest first. */
export async function listJobs() {
  return getJson('api/v1/jobs');
}

/**
 * Follows a job's events (GET /api/v1/jobs/{id}/events, NDJSON) after the `after`-th, calling
 * `onEvent` with each; resolves after the job's last event.
 */
export async function followJob(id, after, onEvent, signal) {
  const response = await fetch(`api/v1/jobs/${encodeURIComponent(id)}/events?after=${after}`, {
    headers: withToken({ accept: 'application/x-ndjson' }), signal,
  });
  if (!response.ok) throw await errorFrom(response);
  await readNdjson(response, onEvent);
}

/** A job as it was submitted (GET /api/v1/jobs/{id}/request): `{study, request, priority}`. */
export async function jobRequest(id) {
  return getJson(`api/v1/jobs/${encodeURIComponent(id)}/request`);
}

/** A done job's document (GET /api/v1/jobs/{id}/result): the document its study's route answers. */
export async function jobResult(id) {
  return getJson(`api/v1/jobs/${encodeURIComponent(id)}/result`);
}

/** A done job's Rerun recording (.rrd bytes). */
export async function jobRecording(id, signal) {
  const response = await fetch(`api/v1/jobs/${encodeURIComponent(id)}/result?format=rrd`, {
    headers: withToken({ accept: 'application/octet-stream' }), signal,
  });
  if (!response.ok) throw await errorFrom(response);
  return response.blob();
}

/** Cancels a job that has not ended (POST /api/v1/jobs/{id}/cancel); resolves to its status. */
export async function cancelJob(id) {
  return (await post(`api/v1/jobs/${encodeURIComponent(id)}/cancel`, null)).json();
}

/** Removes an ended job and its files (DELETE /api/v1/jobs/{id}). */
export async function removeJob(id) {
  const response = await fetch(`api/v1/jobs/${encodeURIComponent(id)}`, {
    method: 'DELETE', headers: withToken({}),
  });
  if (!response.ok) throw await errorFrom(response);
}
