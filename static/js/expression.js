// Expressions of a system definition evaluated in the page, for the one place that needs it: the
// bodies' positions (`positions`) of a stored recording, which records the coordinates but not
// where the definition puts its bodies. The language is the service's (README, "Your own
// systems"): numbers, + - * / ^, parentheses, sin cos tan asin acos atan atan2 sinh cosh tanh exp
// log sqrt abs, pi and declared names; signs bind looser than ^ (-x^2 is -(x^2)) and ^ groups from
// the right (a^b^c is a^(b^c), a^-b^c is a^(-(b^c))), as the server parses them. The server
// checked every stored definition, so a text this parser refuses is a bug of the page: it throws.

const FUNCTIONS = {
  sin: Math.sin, cos: Math.cos, tan: Math.tan, asin: Math.asin, acos: Math.acos, atan: Math.atan,
  sinh: Math.sinh, cosh: Math.cosh, tanh: Math.tanh, exp: Math.exp, log: Math.log, sqrt: Math.sqrt,
  abs: Math.abs, atan2: Math.atan2,
};

/** The tokens of `text`: numbers, names, and the one-character operators. */
function tokens(text) {
  const out = [];
  const pattern = /\s*(?:(\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?)|([\p{L}_][\p{L}\p{N}_]*)|([-+*/^(),]))/uy;
  let at = 0;
  while (at < text.length) {
    if (/^\s*$/.test(text.slice(at))) break;
    pattern.lastIndex = at;
    const m = pattern.exec(text);
    if (!m) throw new Error(`cannot read “${text.slice(at)}” in “${text}”`);
    out.push(m[1] !== undefined ? { number: Number(m[1]) } : m[2] !== undefined ? { name: m[2] } : { op: m[3] });
    at = pattern.lastIndex;
  }
  return out;
}

/**
 * Compiles `text` into a function of an environment (name → number), by recursive descent over
 * its tokens: sum → product → signed power → primary.
 */
export function compile(text) {
  const list = tokens(text);
  let i = 0;
  const peek = () => list[i];
  const isOp = (op) => list[i]?.op === op;
  const expect = (op) => {
    if (!isOp(op)) throw new Error(`expected “${op}” in “${text}”`);
    i += 1;
  };
  // A left-grouped chain of `operand`s joined by the binary operators of `operators`.
  const chain = (operand, operators) => () => {
    let left = operand();
    while (operators[list[i]?.op]) {
      const f = operators[list[i++].op];
      const a = left;
      const b = operand();
      left = (env) => f(a(env), b(env));
    }
    return left;
  };
  const product = chain(() => signed(), { '*': (x, y) => x * y, '/': (x, y) => x / y });
  const sum = chain(product, { '+': (x, y) => x + y, '-': (x, y) => x - y });
  // ("-" | "+")* power: the signs apply to the whole power.
  const signed = () => {
    let negate = false;
    while (isOp('-') || isOp('+')) negate = list[i++].op === '-' ? !negate : negate;
    const p = power();
    return negate ? (env) => -p(env) : p;
  };
  // primary ("^" signed)?: grouped from the right, the exponent may carry signs.
  const power = () => {
    const base = primary();
    if (!isOp('^')) return base;
    i += 1;
    const exponent = signed();
    return (env) => base(env) ** exponent(env);
  };
  const primary = () => {
    const token = peek();
    if (!token) throw new Error(`“${text}” ends too early`);
    i += 1;
    if (token.number !== undefined) return () => token.number;
    if (token.op === '(') {
      const inner = sum();
      expect(')');
      return inner;
    }
    if (token.name === 'pi') return () => Math.PI;
    if (token.name !== undefined && FUNCTIONS[token.name] && isOp('(')) {
      i += 1;
      const args = [sum()];
      while (isOp(',')) {
        i += 1;
        args.push(sum());
      }
      expect(')');
      const f = FUNCTIONS[token.name];
      return (env) => f(...args.map((a) => a(env)));
    }
    if (token.name !== undefined) {
      const { name } = token;
      return (env) => {
        const value = env[name];
        if (value === undefined) throw new Error(`unknown name “${name}” in “${text}”`);
        return value;
      };
    }
    throw new Error(`unexpected “${token.op}” in “${text}”`);
  };
  const f = sum();
  if (i < list.length) throw new Error(`unexpected text after position ${i} in “${text}”`);
  return f;
}

/**
 * The bodies' positions of `definition` at a configuration: a function of q giving the
 * coordinates of every body, body after body (what the server sends as a sample's `bodies`),
 * with the definition's parameters at `params` (its defaults where not given).
 */
export function positionsOf(definition, params = {}) {
  const entries = definition.positions.flat().map((e) => (typeof e === 'number' ? () => e : compile(String(e))));
  const constants = { ...(definition.parameters ?? {}), ...params };
  const names = definition.coordinates;
  return (q) => {
    const env = { ...constants };
    names.forEach((name, k) => { env[name] = q[k]; });
    return entries.map((f) => f(env));
  };
}
