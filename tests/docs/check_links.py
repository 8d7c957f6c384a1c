#!/usr/bin/python3
"""test_docs_links: every relative link in README.md and docs/*.md resolves.

Checks, for README.md, docs/*.md and the READMEs under models/ and tests/:
  1. Markdown links and images `[text](target)` / `![alt](target)` that are
     not URLs: the target, taken relative to the file's folder, exists; a
     `#fragment` names a heading of the target (GitHub's slug rule).
  2. Repository paths written as code, e.g. `docs/shm.md` or
     `src/table/planner_example.c`: those starting with a top-level folder
     of the repository (docs/ src/ include/ scripts/ tests/ calib/ launch/
     models/ bench/ drivers/) exist, relative to the repository root (a
     test or bench named without its .c/.py/.sh counts). Paths with
     placeholders (<...>, *, {...}, ...) are skipped.
  3. Section references written with the repository path, `docs/X.md §N`:
     the section number starts a heading of that file. (A bare `model.md §N`
     cites the design notes, which are not part of the repository.)
  4. Named references `docs/X.md "Title"`: a heading of that file contains
     the title, or a table row starts with it, or a bold run does.
  check_links.py <repo root>    exit 0 ok, 1 broken links (each listed)
  check_links.py --selftest     the checker finds each kind of break in a
                                scratch tree (so the test can fail)
"""
import glob
import os
import re
import sys

TOP = ("docs/", "src/", "include/", "scripts/", "tests/", "calib/", "launch/", "models/",
       "bench/", "drivers/")
LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
CODE = re.compile(r"`([^`\s]+)`")
NAMED = re.compile(r"docs/([A-Za-z_]+\.md) \"([^\"]+)\"")
SECTION = re.compile(r"(?:docs/)?([A-Za-z_]+\.md)\s+§\s*([0-9]+(?:\.[0-9]+)*)")


def slug(heading):
    s = heading.strip().lower()
    s = re.sub(r"[^\w\- ]", "", s)
    return s.replace(" ", "-")


def headings(path):
    out, in_code = [], False
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.startswith("```"):
                in_code = not in_code
            elif not in_code and line.startswith("#"):
                out.append(line.lstrip("#").strip())
    return out


def named_target(doc, title):
    t = title.lower()
    if any(t in h.lower() for h in headings(doc)):
        return True
    text = open(doc, encoding="utf-8").read().lower()
    return ("**" + t) in text or ("\n| " + t) in text


def main():
    root = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else ".")
    files = [os.path.join(root, "README.md")] + sorted(glob.glob(os.path.join(root, "docs", "*.md")))
    files += sorted(glob.glob(os.path.join(root, "models", "*", "README.md")))
    files += sorted(glob.glob(os.path.join(root, "tests", "*", "README.md")))
    bad, n_links, n_paths, n_sections = [], 0, 0, 0
    for path in files:
        rel = os.path.relpath(path, root)
        text = open(path, encoding="utf-8").read()
        in_code = False
        for lineno, line in enumerate(text.splitlines(), 1):
            if line.startswith("```"):
                in_code = not in_code
                continue
            if in_code:
                continue
            for m in LINK.finditer(line):
                target = m.group(1)
                if re.match(r"^[a-z]+:", target):
                    continue  # http:, https:, mailto:
                n_links += 1
                file_part, _, frag = target.partition("#")
                dest = os.path.normpath(os.path.join(os.path.dirname(path), file_part)) if file_part else path
                if not os.path.exists(dest):
                    bad.append("%s:%d: link target %s does not exist" % (rel, lineno, target))
                elif frag and dest.endswith(".md") and frag not in [slug(h) for h in headings(dest)]:
                    bad.append("%s:%d: link %s: no heading '#%s' in %s" % (rel, lineno, target, frag,
                                                                          os.path.relpath(dest, root)))
            for m in CODE.finditer(line):
                p = m.group(1).rstrip(".,;:")
                if not p.startswith(TOP) or re.search(r"[<>*{}\[\]$]|\.\.\.", p):
                    continue
                p = p.split(":")[0]  # file:line
                n_paths += 1
                full = os.path.join(root, p)
                if not any(os.path.exists(full + ext) for ext in ("", ".c", ".py", ".sh")):
                    bad.append("%s:%d: path `%s` does not exist in the repository" % (rel, lineno, p))
            for m in SECTION.finditer(line):
                doc = os.path.join(root, "docs", m.group(1))
                if not m.group(0).startswith("docs/"):
                    continue
                n_sections += 1
                num = m.group(2)
                if not os.path.exists(doc):
                    bad.append("%s:%d: %s: no docs/%s" % (rel, lineno, m.group(0), m.group(1)))
                elif not any(re.match(r"^%s[ .]" % re.escape(num), h) for h in headings(doc)):
                    bad.append("%s:%d: %s: docs/%s has no section %s" % (rel, lineno, m.group(0),
                                                                         m.group(1), num))
            for m in NAMED.finditer(line):
                doc = os.path.join(root, "docs", m.group(1))
                n_sections += 1
                if not os.path.exists(doc):
                    bad.append("%s:%d: %s: no docs/%s" % (rel, lineno, m.group(0), m.group(1)))
                elif not named_target(doc, m.group(2)):
                    bad.append("%s:%d: %s: no heading, table row or bold text '%s' in docs/%s"
                               % (rel, lineno, m.group(0), m.group(2), m.group(1)))
    for b in bad:
        print("BROKEN: " + b)
    print("%d files: %d links, %d repository paths, %d section references checked, %d broken"
          % (len(files), n_links, n_paths, n_sections, len(bad)))
    return 1 if bad else 0


def selftest():
    import subprocess
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        os.makedirs(os.path.join(d, "docs"))
        with open(os.path.join(d, "docs", "a.md"), "w") as f:
            f.write("# A\n## 1. One\n")
        cases = {"[x](docs/missing.md)": "does not exist", "[x](docs/a.md#nope)": "no heading",
                 "`src/missing.c`": "does not exist in the repository",
                 "docs/a.md §2": "has no section 2", 'docs/a.md "Two"': "no heading, table row"}
        for text, want in cases.items():
            with open(os.path.join(d, "README.md"), "w") as f:
                f.write('ok: [a](docs/a.md#1-one), `docs/a.md`, docs/a.md §1, docs/a.md "One"\n' + text + "\n")
            r = subprocess.run([sys.executable, __file__, d], capture_output=True, text=True)
            if r.returncode != 1 or want not in r.stdout or r.stdout.count("BROKEN") != 1:
                print("selftest FAILED on %r:\n%s" % (text, r.stdout))
                return 1
    print("selftest: %d kinds of broken reference found, 0 false alarms" % len(cases))
    return 0


if __name__ == "__main__":
    sys.exit(selftest() if sys.argv[1:] == ["--selftest"] else main())
