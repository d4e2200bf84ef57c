// Jobs on the page: a study section's "Run as a job" submits its request to POST /api/v1/jobs
// instead of streaming it (`jobStream`), follows the job's events as its progress and draws the
// job's document when it is done, exactly as if it had streamed; the Jobs section lists the
// caller's jobs (GET /api/v1/jobs, polled while one has not ended) with their progress, and shows a
// done job's result in its study's section, downloads its document or recording, cancels or
// removes it. The server keeps the jobs, so a closed or reloaded tab loses none of them.

import {
  ApiError, cancelJob, followJob, jobRecording, jobRequest, jobResult, listJobs, removeJob, submitJob,
} from './api.js';
import { CANCEL_PRESSED } from './study-stream.js';
import { el, saveBlob, sizeText } from './common.js';
import { when } from './library.js';

/** Dispatched on `document` when the page submits a job, and when one it follows ends. */
export const JOB_CHANGED = 'geomint:job-changed';

/** How often the list is read again while a job has not ended, in ms. */
const POLL_MS = 1500;

/** A job's id as the page shows it: its first eight digits. */
export const shortId = (id) => id.slice(0, 8);

/**
 * A stream function for `StudyStream.stream` that runs the study `study` (its route's name) as
 * a job: it submits the body, turns the job's events into `progress` lines, and once the job is
 * done hands on its document as the `result` line, as the study's own stream would. The section's
 * Cancel cancels the job; a newer run in the section only stops following it (it goes on in the
 * Jobs section). `onSubmitted(status)` is told the job.
 */
export function jobStream(study, onSubmitted = () => {}) {
  return async (body, onLine, signal) => {
    const job = await submitJob(study, body, signal);
    onSubmitted(job);
    document.dispatchEvent(new CustomEvent(JOB_CHANGED, { detail: job }));
    const label = `Job ${shortId(job.id)}`;
    signal.addEventListener('abort', () => {
      if (signal.reason === CANCEL_PRESSED) cancelJob(job.id).catch(() => {});
    });
    let last = null;
    await followJob(job.id, 0, (event) => {
      last = event;
      onLine({ type: 'progress', done: event.cells_done, total: event.cells, label });
    }, signal);
    document.dispatchEvent(new CustomEvent(JOB_CHANGED, { detail: job }));
    if (last?.state === 'done') {
      onLine({ type: 'result', ...(await jobResult(job.id)) });
    } else if (last?.state === 'failed') {
      throw new ApiError(last.error ?? { code: 'internal', message: `job ${shortId(job.id)} failed` });
    } else if (last?.state === 'cancelled') {
      throw new DOMException(`job ${shortId(job.id)} was cancelled`, 'AbortError');
    } else {
      throw new Error(`the events of job ${shortId(job.id)} ended before it did: its server stopped; ` +
        'the Jobs section shows it again once a server has taken it up');
    }
  };
}

/** The Jobs section: the caller's jobs, newest first, with what can be done with each. */
export class JobsPanel {
  /**
   * @param {HTMLElement} root the section
   * @param {Record<string, {section: string, show: (request: object, doc: object) => void}>} studies
   *   the sections that show a study's document, by study name
   */
  constructor(root, studies) {
    const $ = (id) => root.querySelector(`#jobs-${id}`);
    Object.assign(this, {
      root, studies, list: $('list'), status: $('status'), error: $('error'), refreshButton: $('refresh'),
    });
    /** The jobs last listed (for tests), oldest first as the API lists them. */
    this.jobs = [];
    this.timer = null;
    this.refreshButton.addEventListener('click', () => this.refresh());
    document.addEventListener(JOB_CHANGED, () => this.refresh());
    // The list reads the jobs again when the tab comes back into view.
    document.addEventListener('visibilitychange', () => {
      if (!document.hidden) this.refresh();
    });
  }

  setState(state) {
    this.root.dataset.jobsState = state;
  }

  /** Reads the list again, and keeps reading it while a job has not ended. */
  async refresh() {
    clearTimeout(this.timer);
    this.timer = null;
    try {
      this.jobs = await listJobs();
      this.error.hidden = true;
    } catch (error) {
      // A server without a jobs directory answers 404: the section says so and stops asking.
      this.error.hidden = false;
      this.error.textContent = error instanceof ApiError && error.status === 404
        ? `This server keeps no jobs: ${error.message}.`
        : `The jobs could not be listed: ${error.message}`;
      this.setState('error');
      return;
    }
    this.render();
    const running = this.jobs.some((j) => !ENDED.has(j.state));
    this.setState(running ? 'running' : 'idle');
    // Two reads in flight at once (a poll and a submission) leave one timer between them.
    clearTimeout(this.timer);
    this.timer = running && !document.hidden ? setTimeout(() => this.refresh(), POLL_MS) : null;
  }

  render() {
    const newest = [...this.jobs].reverse();
    this.list.replaceChildren(...newest.map((job) => this.row(job)));
    const unfinished = this.jobs.filter((j) => !ENDED.has(j.state)).length;
    this.status.textContent = this.jobs.length
      ? `${this.jobs.length} job${this.jobs.length === 1 ? '' : 's'}` +
        (unfinished ? `, ${unfinished} not ended (the list follows them).` : ', every one ended.')
      : 'No jobs yet: “Run as a job” in a study’s section submits one.';
  }

  /** One row: the study, its state and progress, when it was submitted, and its actions. */
  row(job) {
    const what = `job ${shortId(job.id)} (${job.study})`;
    const action = (text, label, onclick, extra = {}) => el('button', {
      type: 'button', class: 'secondary small', 'aria-label': `${label} ${what}`, onclick, ...extra,
    }, text);
    const percent = Math.floor((100 * job.cells_done) / Math.max(1, job.cells));
    const shown = this.studies[job.study];
    const done = job.state === 'done';
    const actions = [];
    if (done && shown) actions.push(action('Show', 'Show the result of', () => this.show(job)));
    if (done) {
      actions.push(action('JSON', 'Download the document of', () => this.download(job, 'json')));
      if (job.study !== 'convergence') {
        actions.push(action('.rrd', 'Download the recording of', () => this.download(job, 'rrd')));
      }
    }
    if (!ENDED.has(job.state)) actions.push(action('Cancel', 'Cancel', () => this.act(job, cancelJob)));
    else actions.push(action('Remove', 'Remove', () => this.act(job, removeJob)));
    return el('tr', { 'data-id': job.id, 'data-state': job.state },
      el('th', { scope: 'row', 'data-label': 'Job' }, el('code', { text: shortId(job.id), title: job.id })),
      el('td', { 'data-label': 'Study' }, job.study),
      el('td', { 'data-label': 'State', title: job.error?.message ?? null }, job.state,
        job.error ? el('span', { class: 'field-error', text: ` ${job.error.message}` }) : null),
      el('td', { 'data-label': 'Progress' },
        el('progress', { max: Math.max(1, job.cells), value: job.cells_done, 'aria-label': `Progress of ${what}` }),
        ` ${job.cells_done} of ${job.cells} cells (${percent} %)`),
      el('td', { 'data-label': 'Submitted' }, el('time', { datetime: job.submitted, text: when(job.submitted) })),
      el('td', { class: 'row-actions-cell', 'data-label': 'Actions' }, el('div', { class: 'row-actions' }, actions)));
  }

  /** Shows a done job's document in its study's section (and goes there). */
  async show(job) {
    const target = this.studies[job.study];
    try {
      const [submission, doc] = await Promise.all([jobRequest(job.id), jobResult(job.id)]);
      window.location.hash = `#${target.section}`;
      target.show(submission.request, doc);
    } catch (error) {
      this.fail(`Job ${shortId(job.id)} could not be shown: ${error.message}`);
    }
  }

  /** Saves a done job's document (`json`) or recording (`rrd`). */
  async download(job, format) {
    const name = `geomint-${job.study}-${shortId(job.id)}.${format}`;
    try {
      const blob = format === 'rrd'
        ? await jobRecording(job.id)
        : new Blob([JSON.stringify(await jobResult(job.id))], { type: 'application/json' });
      saveBlob(blob, name);
      this.status.textContent = `Saved ${name} (${sizeText(blob.size)}).`;
    } catch (error) {
      this.fail(`${name} could not be saved: ${error.message}`);
    }
  }

  /** Cancels or removes a job, then reads the list again. */
  async act(job, call) {
    try {
      await call(job.id);
    } catch (error) {
      this.fail(`Job ${shortId(job.id)}: ${error.message}`);
    }
    await this.refresh();
  }

  fail(message) {
    this.error.hidden = false;
    this.error.textContent = message;
  }
}

const ENDED = new Set(['done', 'failed', 'cancelled']);
