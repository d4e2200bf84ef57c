#!/usr/bin/env python3
"""Checks the built book and the README for broken internal links, and their shell examples for
API routes the service does not have.

- Every relative link and image of every page of the built book (mdBook's HTML, with the ids it
  gave the headings) must name a file of the book and, with a `#fragment`, an id in that file.
- Every relative link of README.md must name a file of the repository; a link into the book's
  sources (`docs/src/….md#fragment`) must name an id of that chapter's built page.
- Every `/api/v1/…` path in a `sh` code block of the README or the book must match a route
  template of the service (`{id}` matches any segment). The templates are given as arguments or,
  without them, read from the route constants of `src/http/mod.rs`.

Usage: check_links.py BOOK_DIR [ROUTE_TEMPLATE …]; prints each problem and exits 1 if any.
Standard library only, so that it runs wherever Python 3 does.
"""
import html.parser
import pathlib
import re
import sys
import urllib.parse

ROOT = pathlib.Path(__file__).resolve().parent.parent


class Page(html.parser.HTMLParser):
    """The ids and the relative links of one HTML page."""

    def __init__(self):
        super().__init__()
        self.ids = set()
        self.links = []

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if attrs.get("id"):
            self.ids.add(attrs["id"])
        if tag == "a" and attrs.get("name"):
            self.ids.add(attrs["name"])
        for key in ("href", "src"):
            value = attrs.get(key)
            if value and (tag, key) in {("a", "href"), ("img", "src")}:
                self.links.append(value)


def is_internal(url):
    parts = urllib.parse.urlsplit(url)
    return not parts.scheme and not parts.netloc


def parse(path, cache={}):
    if path not in cache:
        page = Page()
        page.feed(path.read_text(encoding="utf-8"))
        cache[path] = page
    return cache[path]


def shown(path):
    """A path as a message shows it: from the repository's root where it is inside."""
    try:
        return path.relative_to(ROOT)
    except ValueError:
        return path


def check_target(source, target, fragment, problems, what):
    if not target.exists():
        problems.append(f"{source}: {what} names {shown(target)}, which does not exist")
        return
    if fragment and target.suffix == ".html":
        if urllib.parse.unquote(fragment) not in parse(target).ids:
            problems.append(f"{source}: {what} names #{fragment} in {target.name}, which has no such id")


def check_book(book, problems):
    pages = sorted(book.rglob("*.html"))
    # mdBook's own pages (the print page repeats every chapter, 404 is a template).
    for page in (p for p in pages if p.name not in {"print.html", "404.html", "toc.html"}):
        for url in parse(page).links:
            if not is_internal(url) or url.startswith("#!"):
                continue
            parts = urllib.parse.urlsplit(url)
            target = (page.parent / urllib.parse.unquote(parts.path)).resolve() if parts.path else page
            check_target(page.relative_to(book), target, parts.fragment, problems, f"the link {url}")
    return len(pages)


MD_LINK = re.compile(r"\]\(([^)\s]+)\)")


def check_readme(book, problems):
    readme = ROOT / "README.md"
    for url in MD_LINK.findall(readme.read_text(encoding="utf-8")):
        if not is_internal(url):
            continue
        parts = urllib.parse.urlsplit(url)
        target = (ROOT / urllib.parse.unquote(parts.path)).resolve()
        if not target.exists():
            problems.append(f"README.md: the link {url} names a file that does not exist")
            continue
        src = (ROOT / "docs" / "src").resolve()
        if parts.fragment and target.suffix == ".md" and src in target.parents:
            built = book / target.relative_to(src).with_suffix(".html")
            check_target("README.md", built, parts.fragment, problems, f"the link {url}")


SH_BLOCK = re.compile(r"^```(?:sh|bash|console)\n(.*?)^```", re.S | re.M)
ROUTE_IN_TEXT = re.compile(r"/api/v1/[A-Za-z0-9_./{}\-…]*")
ROUTE_CONST = re.compile(r'pub const \w+: &str = "(/[^"]*)";')


def route_pattern(template):
    return re.compile("^" + re.sub(r"\\\{[^}]*\\\}", "[^/]+", re.escape(template)) + "$")


def check_routes(templates, problems):
    patterns = [route_pattern(t) for t in templates]
    files = [ROOT / "README.md"] + sorted((ROOT / "docs" / "src").rglob("*.md"))
    count = 0
    for path in files:
        for block in SH_BLOCK.findall(path.read_text(encoding="utf-8")):
            for route in ROUTE_IN_TEXT.findall(block):
                route = route.split("?")[0].rstrip(".")
                if "…" in route or "{" in route:
                    continue
                count += 1
                if not any(p.match(route) for p in patterns):
                    problems.append(f"{path.relative_to(ROOT)}: a shell example uses {route}, "
                                    "which is no route of the service")
    return count


def main():
    if len(sys.argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    book = pathlib.Path(sys.argv[1]).resolve()
    templates = sys.argv[2:] or ROUTE_CONST.findall((ROOT / "src/http/mod.rs").read_text(encoding="utf-8"))
    if not templates:
        print("check_links: no route templates found", file=sys.stderr)
        return 2
    problems = []
    pages = check_book(book, problems)
    check_readme(book, problems)
    routes = check_routes(templates, problems)
    problems = list(dict.fromkeys(problems))
    for problem in problems:
        print(f"check_links: {problem}", file=sys.stderr)
    print(f"check_links: {pages} pages, {routes} routes in shell examples, {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
