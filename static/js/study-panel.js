// What the work–precision and convergence sections share: a study spec (JSON in a text box) run
// as an NDJSON stream (study-stream.js) with a progress bar and a status line, drawn as the
// settings arrive, a table of the result, a download button, and the section's state in
// `data-{stateKey}` (idle, running, done, error). The elements are found by `prefix`:
// #{prefix}-spec, -run, -status, -progress, -legend, -readout, -table, -form and #err-{prefix}.
// "Run as a job" (#{prefix}-run-job) submits the spec as a job of `study` and draws the job's
// document when it is done; the Jobs section shows a done job's document here (`show`).
// A subclass gives `stream(body, onLine, signal)`, `describe(point)` (the status line after a
// setting), `draw(points, result)` (result null while streaming), `renderTable(result)` and
// `download()`.

import { ApiError } from './api.js';
import { StudyStream, OUTCOME, showRequest } from './study-stream.js';
import { jobStream } from './jobs.js';

export class StudyPanel {
  /**
   * @param {HTMLElement} root the section
   * @param {string} prefix of the section's element ids
   * @param {string} stateKey dataset key of the state
   * @param {HTMLButtonElement} downloadButton enabled once a study is done
   * @param {string} study the study's route name, for jobs (`work-precision`)
   */
  constructor(root, prefix, stateKey, downloadButton, study) {
    const $ = (id) => root.querySelector(`#${id}`);
    Object.assign(this, {
      root, downloadButton,
      spec: $(`${prefix}-spec`), runButton: $(`${prefix}-run`), status: $(`${prefix}-status`),
      progress: $(`${prefix}-progress`), error: $(`err-${prefix}`), legend: $(`${prefix}-legend`),
      readout: $(`${prefix}-readout`), table: $(`${prefix}-table`), jobButton: $(`${prefix}-run-job`), study,
    });
    this.runner = new StudyStream({ root, stateKey, progress: this.progress, status: this.status, unit: 'settings' });
    /** The last study's points, result and body (for tests and the download). */
    this.last = null;
    $(`${prefix}-form`).addEventListener('submit', (event) => {
      event.preventDefault();
      this.run();
    });
    downloadButton.addEventListener('click', () => this.download());
    this.jobButton.addEventListener('click', () => this.run({ asJob: true }));
    this.runButton.disabled = false;
    this.jobButton.disabled = false;
  }

  /**
   * Runs the study in the text box; a new run supersedes a running one. `asJob` submits it as a
   * job and draws the job's document when it is done.
   */
  async run({ asJob = false } = {}) {
    this.error.textContent = '';
    this.spec.removeAttribute('aria-invalid');
    this.downloadButton.disabled = true;
    let body;
    try {
      body = JSON.parse(this.spec.value);
    } catch (e) {
      this.runner.abort();
      this.fail(`The spec is not JSON: ${e.message}`);
      return;
    }
    const points = [];
    this.last = { body, points, result: null };
    // The readout described a dot of the last study.
    this.readout.textContent = 'Point at a dot to read its setting.';
    for (const key of Object.keys(this.readout.dataset)) delete this.readout.dataset[key];
    this.draw(points, null);
    const stream = asJob ? jobStream(this.study) : (b, onLine, signal) => this.stream(b, onLine, signal);
    const { outcome, result, error } = await this.runner.stream(stream, body, (line) => {
      if (line.type === 'reference') {
        this.runner.showProgress(0, line.total);
        this.status.textContent = `Errors against the ${line.reference}; ${line.total} settings to run…`;
      } else if (line.type === 'point') {
        points.push(line.point);
        this.status.textContent = `${line.done} of ${line.total}: ${this.describe(line.point)}`;
        this.draw(points, null);
      }
    });
    if (outcome === OUTCOME.superseded) return;
    if (outcome !== OUTCOME.done) {
      this.fail(error?.message || String(error), error instanceof ApiError ? error.field : null);
      return;
    }
    this.finish(result);
  }

  /** Shows a done job's study: its spec in the text box and its result drawn. */
  show(body, result) {
    showRequest(this, body);
    this.last = { body, points: [], result: null };
    this.finish(result);
  }

  /** Draws the finished study `result` (of `this.last.body`). */
  finish(result) {
    this.last.result = result;
    this.draw(result.points, result);
    this.renderTable(result);
    this.progress.hidden = true;
    this.status.textContent = `Done: ${result.points.length} settings of ${result.system.id} to t = ${result.t_end}, ` +
      `errors against the ${result.reference}.`;
    this.downloadButton.disabled = false;
    this.runner.setState('done');
  }

  fail(message, field = null) {
    this.progress.hidden = true;
    this.error.textContent = field ? `${field}: ${message.replace(`${field}: `, '')}` : message;
    this.spec.setAttribute('aria-invalid', 'true');
    this.status.textContent = 'The study could not run.';
    this.runner.setState('error');
  }
}
