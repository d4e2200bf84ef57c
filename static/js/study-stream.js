// One computation at a time in a study section (stability, work–precision, convergence, energy
// map, sweep): a new one supersedes the one still running, whose answers are then ignored; Cancel
// aborts it; the section's state (`data-<key>` on its root, for tests) follows it. For the NDJSON
// studies it also reads the stream: `progress` lines (and `point` lines, which carry the same
// done/total) move the progress bar, the `result` line is kept, an `error` line ends the study
// with the API's error, and the other lines go to the section.

import { ApiError } from './api.js';

/**
 * The reason a computation's signal is aborted with when its section's Cancel is pressed (a newer
 * computation aborts it without one): a study run as a job is then cancelled on the server, where
 * a superseded one only stops being followed.
 */
export const CANCEL_PRESSED = 'cancel pressed';

/** What one call of `StudyStream.stream` came to. */
export const OUTCOME = { done: 'done', cancelled: 'cancelled', error: 'error', superseded: 'superseded' };

export class StudyStream {
  /**
   * @param {object} ui
   * @param {HTMLElement} ui.root the section, which carries the state
   * @param {string} ui.stateKey its dataset key (`sweepState` is `data-sweep-state`)
   * @param {HTMLProgressElement} [ui.progress]
   * @param {HTMLElement} [ui.status] the status line
   * @param {HTMLButtonElement} [ui.cancel] enabled while a study runs
   * @param {string} [ui.unit] what the progress counts, for the status line (`cells`)
   */
  constructor({ root, stateKey, progress = null, status = null, cancel = null, unit = 'cells' }) {
    Object.assign(this, { root, stateKey, progress, status, cancel, unit });
    this.controller = null;
    /** The last `progress` (or `point`) line of the current study (for tests). */
    this.lastProgress = null;
    cancel?.addEventListener('click', () => this.cancelPressed());
  }

  setState(state) {
    this.root.dataset[this.stateKey] = state;
  }

  say(text) {
    if (this.status) this.status.textContent = text;
  }

  /** Aborts the running computation, if any. */
  abort() {
    this.controller?.abort();
  }

  /** Aborts the running computation as its Cancel does (a job is cancelled too). */
  cancelPressed() {
    this.controller?.abort(CANCEL_PRESSED);
  }

  /**
   * Starts a computation, aborting the one before: returns its abort signal and `current()`,
   * false once a newer one has started. The section is `running`.
   */
  begin() {
    this.abort();
    const controller = new AbortController();
    this.controller = controller;
    this.lastProgress = null;
    this.setState('running');
    if (this.cancel) this.cancel.disabled = false;
    return { signal: controller.signal, current: () => controller === this.controller };
  }

  /** The progress bar at `done` of `total`. */
  showProgress(done, total) {
    if (!this.progress) return;
    this.progress.hidden = false;
    this.progress.max = Math.max(1, total);
    this.progress.value = done;
  }

  /**
   * Streams `body` through `streamFn(body, onLine, signal)` (an NDJSON route of api.js), handing
   * every line but `progress`, `result`, `error` and `end` to `onLine`. Resolves to
   * {outcome, result, error}: `done` with the result line (without its type), `cancelled`, `error`
   * with the error (an ApiError, or the Error of a stream cut short), or `superseded` when a newer
   * computation started meanwhile (the caller then leaves the section to it). The section's state
   * is `cancelled` or `error` after those outcomes; after `done` the caller draws and sets it.
   */
  async stream(streamFn, body, onLine = () => {}) {
    const run = this.begin();
    let result = null;
    if (this.progress) {
      this.progress.hidden = false;
      this.progress.removeAttribute('value');
    }
    this.say('Starting…');
    try {
      await streamFn(body, (line) => {
        if (!run.current()) return;
        if (line.type === 'progress' || line.type === 'point') {
          this.lastProgress = line;
          this.showProgress(line.done, line.total);
          if (line.type === 'progress') {
            this.say(`${line.label ?? 'Running'}: ${line.done} of ${line.total} ${this.unit} ` +
              `(${Math.floor((100 * line.done) / Math.max(1, line.total))} %).`);
          }
        }
        if (line.type === 'result') {
          const { type: _type, ...rest } = line;
          result = rest;
        } else if (line.type === 'error') {
          throw new ApiError(line.error);
        } else if (line.type !== 'progress' && line.type !== 'end') {
          onLine(line);
        }
      }, run.signal);
    } catch (error) {
      if (!run.current()) return { outcome: OUTCOME.superseded };
      this.finish();
      // A bar that never saw a progress line stays empty rather than indeterminate.
      if (this.progress && !this.lastProgress) this.progress.value = 0;
      if (error?.name === 'AbortError' || run.signal.aborted) {
        this.setState('cancelled');
        return { outcome: OUTCOME.cancelled };
      }
      this.setState('error');
      return { outcome: OUTCOME.error, error };
    }
    if (!run.current()) return { outcome: OUTCOME.superseded };
    this.finish();
    return { outcome: OUTCOME.done, result };
  }

  /** The computation has ended: Cancel is off. */
  finish() {
    if (this.cancel) this.cancel.disabled = true;
  }
}

/**
 * Puts the request `body` of a study that ran elsewhere (a job) in a section's JSON text box
 * `spec`, stopping the section's own computation and clearing its error.
 */
export function showRequest({ runner, spec, error }, body) {
  runner.abort();
  error.textContent = '';
  spec.removeAttribute('aria-invalid');
  spec.value = JSON.stringify(body, null, 2);
}
