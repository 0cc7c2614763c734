#!/usr/bin/env bash
# Every pointer a source comment makes into docs/measurements.md ("docs/measurements.md, <heading>")
# names a heading that exists there, so that a figure moved out of a comment can be found, and a
# renamed heading is noticed. Usage: tests/docs_references.sh SOURCE_DIR
set -euo pipefail
src="${1:-$(cd "$(dirname "$0")/.." && pwd)}"
cd "$src"
exec /usr/bin/python3 - <<'PY'
import pathlib, re, sys
doc = pathlib.Path("docs/measurements.md").read_text()
headings = {l.lstrip("#").strip() for l in doc.splitlines() if l.startswith("## ") or l.startswith("### ")}
bad, count = [], 0
for folder in ("host", "kernels", "bench", "tests", "scripts"):
    for path in sorted(pathlib.Path(folder).rglob("*")):
        if not path.is_file() or path.suffix not in (".h", ".cpp", ".cl", ".sh", ".py", "") or "corpus" in path.parts:
            continue
        try:
            text = path.read_text()
        except UnicodeDecodeError:
            continue
        # A pointer may wrap onto the next comment line: join the comment markers away first.
        flat = re.sub(r"\n\s*(//+|\*|#)\s*", " ", text)
        for m in re.finditer(r'docs/measurements\.md[,:]?\s+("([^"]+)"|([A-Za-z][^).;\n]*))', flat):
            name = (m.group(2) or m.group(3)).strip()
            count += 1
            # The longest prefix of the words that is a heading (a pointer may run on into prose).
            words = name.split()
            if not any(" ".join(words[:k]) in headings for k in range(len(words), 0, -1)):
                bad.append(f"{path}: no heading '{name}' in docs/measurements.md")
for b in bad:
    print("FAIL", b)
print(f"{count - len(bad)} passed, {len(bad)} failed")
sys.exit(1 if bad or count == 0 else 0)
PY
