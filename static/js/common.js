// What every section of the page uses: building elements (`el`) and filling them from the page's
// templates (`expandTemplates`), saving a file the page made (`saveBlob`, `downloadRecording`),
// and reading and writing numbers — as inputs show them, as labels and readouts
// show them, and from what a reader typed (bad text becomes null, so that the API names the
// field). No section-specific code lives here.

/** Creates an element with attributes and children. */
export function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs)) {
    if (value === undefined || value === null || value === false) continue;
    if (key === 'class') node.className = value;
    else if (key === 'text') node.textContent = value;
    else if (key.startsWith('on')) node.addEventListener(key.slice(2), value);
    else node.setAttribute(key, value === true ? '' : String(value));
  }
  for (const child of children.flat()) {
    if (child === null || child === undefined || child === false) continue;
    node.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return node;
}

/** The attributes of a template that hold ids or references to them. */
const ID_ATTRIBUTES = ['id', 'for', 'aria-labelledby', 'aria-describedby'];

/**
 * Fills `host` with a copy of the <template> its `data-template` names. Every "{p}" in an id or a
 * reference to one becomes `prefix` (the host's `data-prefix` unless given), so one template
 * serves several sections; a `data-slot` element of the copy is replaced by the host's own
 * children with the same `data-slot`; elements of the copy with a `data-template` are filled in
 * turn, with the same prefix.
 */
export function fillFromTemplate(host, prefix = host.dataset.prefix ?? '') {
  const copy = document.getElementById(host.dataset.template).content.cloneNode(true);
  for (const node of copy.querySelectorAll('*')) {
    for (const name of ID_ATTRIBUTES) {
      const value = node.getAttribute(name);
      if (value?.includes('{p}')) node.setAttribute(name, value.replaceAll('{p}', prefix));
    }
  }
  for (const slot of copy.querySelectorAll('[data-slot]')) {
    slot.replaceWith(...host.querySelectorAll(`:scope > [data-slot="${slot.dataset.slot}"]`));
  }
  for (const inner of copy.querySelectorAll('[data-template]')) fillFromTemplate(inner, prefix);
  host.append(copy);
}

/** Fills every element of the page that names a template (see fillFromTemplate). */
export function expandTemplates(root = document) {
  for (const host of root.querySelectorAll('[data-template]')) fillFromTemplate(host);
}

/**
 * Saves the recording `fetchBlob()` makes as `name`, with `button` off meanwhile; says so in
 * `status`, or why not in `error`. The server computes what it records again, which can take a
 * while: the status says so.
 */
export async function downloadRecording({ button, status, error, name, fetchBlob }) {
  button.disabled = true;
  error.textContent = '';
  status.textContent = `Recording ${name} (the server computes it again)…`;
  try {
    const blob = await fetchBlob();
    saveBlob(blob, name);
    status.textContent = `Saved ${name} (${sizeText(blob.size)}).`;
  } catch (problem) {
    error.textContent = `The recording could not be made: ${problem?.message || problem}`;
    status.textContent = 'The recording could not be made.';
  } finally {
    button.disabled = false;
  }
}

/** Offers `blob` as a file download named `name`. */
export function saveBlob(blob, name) {
  const url = URL.createObjectURL(blob);
  const link = el('a', { href: url, download: name });
  document.body.append(link);
  link.click();
  link.remove();
  // The download has started by then; the object URL only keeps the bytes alive.
  setTimeout(() => URL.revokeObjectURL(url), 10_000);
}

/** A file size in KiB or MiB. */
export function sizeText(bytes) {
  if (bytes >= 1024 * 1024) return `${(bytes / (1024 * 1024)).toFixed(1)} MiB`;
  return `${Math.max(1, Math.round(bytes / 1024))} KiB`;
}

/** A number for labels, tables and readouts: `digits` significant digits, exponent when tiny or huge. */
export function fmt(x, digits = 4) {
  if (x == null || !Number.isFinite(x)) return '—';
  if (x !== 0 && (Math.abs(x) < 1e-3 || Math.abs(x) >= 1e5)) return x.toExponential(digits - 1);
  return String(+x.toPrecision(digits));
}

/** An error as the study tables show it: three significant digits, always with an exponent. */
export function fmtError(e) {
  return e == null ? '—' : e.toExponential(2);
}

/** `count` and the noun, plural when count is not 1: `1 run`, `3 runs`. */
export function plural(count, noun, nouns = `${noun}s`) {
  return `${count} ${count === 1 ? noun : nouns}`;
}

/** A number as an input shows it (shortest round-trip form). */
export function numberText(x) {
  return Number.isFinite(x) ? String(x) : '';
}

/** Parses an input's text: a finite number, or null (the API then names the field). */
export function parseNumber(text) {
  const t = String(text).trim();
  if (t === '') return null;
  const x = Number(t);
  return Number.isFinite(x) ? x : null;
}

/** A count (grid points, samples): a whole number as a number; anything else as typed. */
export function parseCount(text) {
  const x = parseNumber(text);
  return x !== null && Number.isInteger(x) ? x : String(text).trim() || null;
}

/** Parses a comma- or space-separated list of numbers; bad entries become null. */
export function parseList(text) {
  const parts = String(text).split(/[\s,;]+/).filter((s) => s !== '');
  return parts.map(parseNumber);
}
