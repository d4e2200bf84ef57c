// The bearer token the page sends with every API request, typed into the header's token field
// and kept in the browser's local storage (never in a cookie or the address). A server without a
// tokens file ignores it; one with a tokens file answers with what the token may do (the
// recordings list says which recordings it may delete).

const KEY = 'geomint.token';

/** The token kept in this browser ('' for none). */
export function token() {
  try {
    return localStorage.getItem(KEY) || '';
  } catch {
    return '';
  }
}

/** `headers` with `Authorization: Bearer …` added when a token is kept. */
export function withToken(headers = {}) {
  const kept = token();
  return kept ? { ...headers, authorization: `Bearer ${kept}` } : headers;
}

/**
 * Sets up the header's token field: keeps a new token when the field changes (or forgets it when
 * emptied), says so beside it, and calls `onChange` so the page can list again what the user may
 * do. A token the server does not know shows as its refusal where the page next asks.
 */
export function setupTokenField(input, status, onChange = () => {}) {
  if (!input) return;
  input.value = token();
  const show = () => {
    status.textContent = token() ? 'kept in this browser' : '';
  };
  input.addEventListener('change', () => {
    try {
      if (input.value.trim()) localStorage.setItem(KEY, input.value.trim());
      else localStorage.removeItem(KEY);
    } catch {
      // Storage refused (a private window): the token is not kept.
    }
    show();
    onChange();
  });
  show();
}
