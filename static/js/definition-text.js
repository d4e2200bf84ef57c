// A system definition as the Your-system section writes it in its text fields and in its links:
// the fields' text read into a definition's parts (parameters, matrices, positions) and written
// back, and the #system=… link (the definition and the run settings as base64url JSON).

import { numberText } from './common.js';

/** A text the page cannot turn into a definition, at field `field`. */
export class DefinitionProblem extends Error {
  constructor(field, message) {
    super(message);
    this.field = field;
  }
}

/** `raw` trimmed, with `start` moved to where the trimmed text begins. */
export function trimmed(raw, start) {
  return { text: raw.trim(), start: start + raw.length - raw.trimStart().length };
}

/**
 * The parts of `text` between `separator`s outside parentheses (so that `atan2(y, x)` stays
 * whole), trimmed, each with the offset where it starts in the input (`from` is the offset of
 * `text` itself).
 */
export function splitParts(text, separator, from = 0) {
  const parts = [];
  let depth = 0;
  let begin = 0;
  for (let i = 0; i <= text.length; i++) {
    const c = text[i];
    if (c === '(') depth += 1;
    else if (c === ')') depth = Math.max(0, depth - 1);
    if (i === text.length || (c === separator && depth === 0)) {
      parts.push(trimmed(text.slice(begin, i), from + begin));
      begin = i + 1;
    }
  }
  return parts;
}

/** The lines of `text` that are not blank, trimmed, with their offsets. */
export function nonBlankLines(text) {
  let offset = 0;
  const out = [];
  for (const line of text.split('\n')) {
    const part = trimmed(line, offset);
    if (part.text) out.push({ ...part, end: offset + line.length });
    offset += line.length + 1;
  }
  return out;
}

/** An entry as the API takes it: a number when the text is one, else the expression. */
export function entryValue(text) {
  return /^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$/.test(text) ? Number(text) : text;
}

/** An entry (number or expression) as the inputs show it. */
export function entryText(entry) {
  return typeof entry === 'number' ? numberText(entry) : entry ?? '';
}

/** Rows of entries as a text area shows them: one row per line, entries comma-separated. */
export function rowsText(rows) {
  return (rows ?? []).map((row) => row.map(entryText).join(', ')).join('\n');
}

/** A mass as its input shows it: `m`, a diagonal `m1, m2`, or rows separated by `;`. */
export function massText(mass) {
  if (mass === undefined || mass === null) return '';
  if (!Array.isArray(mass)) return entryText(mass);
  if (mass.some(Array.isArray)) return mass.map((row) => row.map(entryText).join(', ')).join('; ');
  return mass.map(entryText).join(', ');
}

/** Text as base64url (of its UTF-8 bytes), and back. */
function toBase64Url(text) {
  let binary = '';
  for (const byte of new TextEncoder().encode(text)) binary += String.fromCharCode(byte);
  return btoa(binary).replace(/\+/g, '-').replace(/\//g, '_').replace(/=+$/, '');
}

function fromBase64Url(text) {
  const binary = atob(text.replace(/-/g, '+').replace(/_/g, '/'));
  return new TextDecoder('utf-8', { fatal: true }).decode(Uint8Array.from(binary, (c) => c.charCodeAt(0)));
}

/** The link that opens the page on `state` ({definition, run}). */
export function systemLink(state) {
  const { origin, pathname } = window.location;
  return `${origin}${pathname}#system=${toBase64Url(JSON.stringify(state))}`;
}

/**
 * The state a location hash holds (`#system=…`): {definition, run}, null when the hash is about
 * something else, or {invalid: reason}.
 */
export function linkedSystem(hash) {
  const match = /^#system=(.*)$/.exec(hash || '');
  if (!match) return null;
  try {
    const state = JSON.parse(fromBase64Url(decodeURIComponent(match[1])));
    if (!state?.definition || !Array.isArray(state.definition.coordinates)) {
      return { invalid: 'it holds no definition with coordinates' };
    }
    return state;
  } catch {
    return { invalid: 'its text is not a definition the page wrote (it may have been cut short)' };
  }
}
