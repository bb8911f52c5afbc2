#!/usr/bin/python3
"""scripts/check_sizes.py: the size limits of the library's rooms, checked.

No library file (.h, .cc) has more than --max-file lines (default 700) and no function, member
function or constructor defined in one has a body of more than --max-function lines (default
80), counted from the line where its declarator starts to the line of its closing brace.

Usage: check_sizes.py [--max-file N] [--max-function N] [--expect N] [--known FILE] [--list] DIR...
Prints one line per violation (FILE:LINE: ...) and exits 1 when there is any, or, with
--expect N, when the count is not N (the test of this check on a tree with known faults).
--list prints every function with its length instead, longest first.
--known FILE names rooms that are still too large and not yet split, one `PATH: NAME` per line
(NAME: the function, or `file`; `#` starts a comment): they are printed but do not fail the check,
and a listed room that is no longer too large fails it until it is struck from the list, so the
list can only shrink.

The C++ is read with a small scanner, not a compiler: comments, string and character literals
(raw strings too) and preprocessor lines are blanked first; then a brace opened at namespace or
class scope whose head (the text since the previous `;`, `{` or `}`) ends in a parameter list,
optionally followed by qualifiers, a trailing return type or a constructor's initialiser list,
is a function body. Lambdas and local classes count towards their enclosing function.
"""
import argparse
import os
import re
import sys

# `extern "C" {`: the literal is blanked to `" "` before the heads are read.
SCOPE_HEAD = re.compile(r"\b(namespace|class|struct|union|enum)\b|\bextern\s*(\"[^\"]*\")?\s*$")
CONTROL = re.compile(r"^(if|for|while|switch|catch|do|else|try|return)\b")
QUALIFIERS = re.compile(r"(\s*(const|noexcept|override|final|mutable|&|&&|volatile)\b|\s*->[^{;]*)*\s*$")


def blank(text):
    """Comments, literals and preprocessor lines replaced by spaces (newlines kept)."""
    out = []
    i, n = 0, len(text)
    line_start = True
    while i < n:
        c = text[i]
        if line_start and c == "#":
            # A preprocessor line (with continuations).
            while i < n and text[i] != "\n":
                if text[i] == "\\" and i + 1 < n and text[i + 1] == "\n":
                    out.append(" \n")
                    i += 2
                    continue
                out.append(" ")
                i += 1
            continue
        if c == "\n":
            line_start = True
            out.append(c)
            i += 1
            continue
        if not c.isspace():
            line_start = False
        if text.startswith("//", i):
            while i < n and text[i] != "\n":
                out.append(" ")
                i += 1
            continue
        if text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
            continue
        m = re.match(r'R"([^()\\ ]{0,16})\(', text[i:i + 20])
        if m and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            end = text.find(")" + m.group(1) + '"', i + m.end())
            end = n if end < 0 else end + len(m.group(1)) + 2
            out.append('""' + re.sub(r"[^\n]", " ", text[i + 2:end]))
            i = end
            continue
        if c in "\"'":
            # A digit separator (1'000) is not a character literal.
            if c == "'" and i > 0 and text[i - 1].isalnum() and i + 1 < n and text[i + 1].isalnum():
                out.append(" ")
                i += 1
                continue
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            out.append(c + " " * (min(j, n) - i - 1) + (c if j < n else ""))
            i = j + 1
            continue
        out.append(c)
        i += 1
    return "".join(out)


def function_name(head):
    """The declarator's name: the identifier before the first top-level '('."""
    depth = 0
    for k, ch in enumerate(head):
        if ch == "<":
            depth += 1
        elif ch == ">" and depth > 0:
            depth -= 1
        elif ch == "(" and depth == 0:
            m = re.search(r"((?:[A-Za-z_~][\w]*::)*~?[A-Za-z_]\w*|operator\s*\S+)\s*$", head[:k])
            return m.group(1) if m else "?"
    return "?"


def is_function_head(head):
    h = head.strip()
    if not h or CONTROL.match(h) or "=" in re.sub(r"operator\s*[=!<>+\-*/%&|^]+", "", h.split("(")[0]):
        return False
    if SCOPE_HEAD.search(h.split("(")[0]):
        return False
    # Strip a constructor's initialiser list: ") : a_(x), b_{y}" -> ")".
    body = h
    # The list is complete only when its last item is: at `c_{` in ") : a_(x), c_{y} {" the head
    # ends in `c_`, and that brace is c_'s initialiser, not the body.
    m = re.search(r"\)\s*(?:noexcept\s*)?:\s*[\w:]+\s*[({]", body)
    if m:
        if not re.search(r"[)}]\s*$", body):
            return False
        body = body[:m.start() + 1]
    body = QUALIFIERS.sub("", body)
    return body.endswith(")")


def functions(text):
    """Yields (name, first line, last line) of every function body at namespace or class scope."""
    code = blank(text)
    line_of = []
    line = 1
    for ch in code:
        line_of.append(line)
        if ch == "\n":
            line += 1
    # Per open brace: ("scope" | "function" | "other", name, first line, head start). An "other"
    # brace at namespace or class scope is a brace initialiser (`int a_{0};`, a constructor's
    # `: a_{x}, b_(y) {`, a default argument `= {}`): its head goes on after it closes.
    stack = []
    head_start = 0
    found = []
    for i, ch in enumerate(code):
        if ch == "{":
            head = code[head_start:i]
            inside_function = any(k[0] == "function" for k in stack)
            if not inside_function and is_function_head(head):
                s = head_start + (len(head) - len(head.lstrip()))
                stack.append(("function", function_name(head.strip()), line_of[s], None))
            elif not inside_function and (SCOPE_HEAD.search(head) or not head.strip()):
                stack.append(("scope", None, None, None))
            else:
                stack.append(("other", None, None, None if inside_function else head_start))
            head_start = i + 1
        elif ch == "}":
            head_start = i + 1
            if stack:
                kind, name, first, resume = stack.pop()
                if kind == "function":
                    found.append((name, first, line_of[i]))
                elif resume is not None:
                    head_start = resume
        elif ch == ";":
            head_start = i + 1
        elif ch == ":" and code[i - 1:i] != ":" and code[i + 1:i + 2] != ":":
            # "public:" / "private:" labels end a head too.
            if re.search(r"\b(public|private|protected)\s*$", code[head_start:i]):
                head_start = i + 1
    return found


def source_files(dirs):
    for d in dirs:
        for root, _, names in os.walk(d):
            for name in sorted(names):
                if name.endswith((".h", ".cc")):
                    yield os.path.join(root, name)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("dirs", nargs="+")
    p.add_argument("--max-file", type=int, default=700)
    p.add_argument("--max-function", type=int, default=80)
    p.add_argument("--expect", type=int)
    p.add_argument("--list", action="store_true")
    p.add_argument("--known")
    a = p.parse_args()
    violations = []
    listing = []
    count = 0
    for path in sorted(source_files(a.dirs)):
        count += 1
        with open(path, encoding="utf-8") as f:
            text = f.read()
        lines = text.count("\n") + (0 if text.endswith("\n") or not text else 1)
        if lines > a.max_file:
            violations.append((f"{path}: file",
                               f"{path}:1: file has {lines} lines (at most {a.max_file})"))
        for name, first, last in functions(text):
            length = last - first + 1
            listing.append((length, f"{path}:{first}: {name}"))
            if length > a.max_function:
                violations.append((f"{path}: {name}",
                                   f"{path}:{first}: function {name} has {length} lines "
                                   f"(at most {a.max_function})"))
    if count == 0:
        print("check_sizes: no .h or .cc files found", file=sys.stderr)
        return 2
    if a.list:
        for length, where in sorted(listing, reverse=True):
            print(f"{length:5d} {where}")
        return 0
    known = set()
    if a.known:
        with open(a.known, encoding="utf-8") as f:
            for raw in f:
                entry = raw.split("#", 1)[0].strip()
                if entry:
                    known.add(entry)
    found = {key for key, _ in violations}
    new = [text for key, text in violations if key not in known]
    for key, text in violations:
        if key in known:
            print(f"{text} [known: {a.known}]")
    for v in new:
        print(v)
    stale = sorted(known - found)
    for k in stale:
        print(f"{k}: listed in {a.known} but no longer too large: strike it from the list")
    if a.expect is not None:
        if len(violations) != a.expect:
            print(f"check_sizes: expected {a.expect} violations, found {len(violations)}")
            return 1
        print(f"check_sizes: {len(violations)} violations found, as expected ({count} files)")
        return 0
    if new or stale:
        print(f"check_sizes: {len(new)} rooms too large, {len(stale)} stale entries "
              f"({count} files checked)")
        return 1
    print(f"check_sizes: {count} files checked: files <= {a.max_file} lines, "
          f"functions <= {a.max_function} lines"
          + (f" ({len(known)} known exceptions still to split, {a.known})" if known else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
