// One section of the page at a time. The page has nine sections (the elements with `data-view`:
// Simulation, Your system, Recordings, Stability, …); a reader who comes for one of them should not
// scroll past the eight others, so only the one the address names is shown. The address keeps
// working as it did when the page was one long column: `#stability` (or the id of anything inside
// a section, such as `#results` or `#sim-form`) shows that section, `#system=…` the Your-system
// section, `#recording=…` the Recordings section and `#orbits=…` the Phase-space section; no hash
// shows the Simulation section. The header's section links are ordinary links to those hashes,
// the one shown marked `aria-current="page"`; Back and Forward move between the sections a reader
// opened.

/** The section a hash like `#system=…` or `#recording=…` opens. */
const LINK_SECTIONS = { system: 'your-system', recording: 'recordings', orbits: 'phase-space' };

export class Sections {
  /**
   * @param {HTMLElement} nav the header's section links
   * @param {string} first the id of the section shown when the hash names none
   */
  constructor(nav, first) {
    this.nav = nav;
    this.first = first;
    this.views = [...document.querySelectorAll('[data-view]')];
    window.addEventListener('hashchange', () => this.follow(true));
    this.follow(false);
  }

  /** The id of the section `hash` names. */
  sectionOf(hash) {
    const name = decodeURIComponent((hash || '').replace(/^#/, ''));
    const link = /^(\w+)=/.exec(name);
    if (link) return LINK_SECTIONS[link[1]] ?? this.first;
    const target = name ? document.getElementById(name) : null;
    return target?.closest('[data-view]')?.id ?? this.first;
  }

  /** The section on show. */
  get current() {
    return this.views.find((v) => !v.hidden)?.id ?? null;
  }

  /** Shows the section the address names; after a link was followed, scrolls to what it names. */
  follow(scroll) {
    const id = this.sectionOf(window.location.hash);
    this.show(id);
    if (!scroll) return;
    const name = decodeURIComponent(window.location.hash.replace(/^#/, ''));
    const target = document.getElementById(name);
    // A section's own link starts at the top of the page, where its links are.
    if (target && target.id !== id) target.scrollIntoView({ block: 'start' });
    else window.scrollTo(0, 0);
  }

  /** Shows section `id` alone and marks its link. */
  show(id) {
    for (const view of this.views) view.hidden = view.id !== id;
    for (const link of this.nav.querySelectorAll('a')) {
      if (link.getAttribute('href') === `#${id}`) link.setAttribute('aria-current', 'page');
      else link.removeAttribute('aria-current');
    }
    document.body.dataset.section = id;
  }
}
