#!/usr/bin/python3
"""Bash completions and man pages agree with the programs' --help.

usage: test_completion.py COMPLETIONS_DIR PROG=PATH[:MANPAGE] ...
(PROG= with no path: a program this tree does not build; not checked)

For every program: completions/PROG is loaded into a bash, once on top of
bash-completion (/usr/share/bash-completion/bash_completion, as an
interactive shell has it) and once alone, and completion is asked the way
a user presses TAB (COMP_WORDS, COMP_CWORD, the function `complete -p`
names). What `PROG --help` (and `PROG CMD --help` for each command under
"Commands:") prints is the reference:
  - the commands offered after PROG are exactly the commands of --help;
  - the options offered after `-` include every option --help defines (at
    the start of a line or in [brackets] of the usage) and nothing that
    --help does not mention;
  - after an option that takes a value (a metavariable follows it) no
    option is offered, and where --help lists the values (OPT A|B|C)
    exactly those; after a flag the options are offered again;
  - the man page mentions every option --help defines.
Every completion file must belong to one of the programs given, and every
program must have one. Exit 1 with every mismatch listed.
"""
import os
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402

R = report.Report("pkg-completion")

OPT = r"--?[A-Za-z][A-Za-z0-9-]*"
BASH_COMPLETION = "/usr/share/bash-completion/bash_completion"
FILES = ("data.csv", "notes.txt")


def run_help(argv):
    p = subprocess.run(argv + ["--help"], capture_output=True, text=True, timeout=20)
    if p.returncode != 0:
        raise SystemExit(f"test_completion: {' '.join(argv)} --help exited {p.returncode}: {p.stderr}")
    return p.stdout


def help_options(text):
    """(defined, mentioned, takes_value, values) of one --help text."""
    defined, takes, values = set(), set(), {}
    mentioned = set(m.group(2) for m in re.finditer(r"(^|[^A-Za-z0-9-])(" + OPT + ")", text, re.M))
    for line in text.splitlines():
        # option lines: "  -c, --config FILE   text" / "  --chord      text"
        m = re.match(r"^\s+((?:" + OPT + r",?\s)*?" + OPT + r")((?: [^ ]+)?)(?:\s{2,}|$)", line)
        if m and m.group(1).lstrip().startswith("-"):
            names = re.findall(OPT, m.group(1))
            defined.update(names)
            meta = (m.group(2) or "").strip()
            if re.match(r"[A-Z]", meta):
                takes.update(names)
            elif re.fullmatch(r"[A-Za-z0-9]+(\|[A-Za-z0-9]+)+", meta):
                takes.update(names)
                for n in names:
                    values[n] = set(meta.split("|"))
    # usage brackets and required options: "[--opt METAVAR]", "-o FILE", "[--flag]"
    for m in re.finditer(r"(^|[\s\[])(" + OPT + r")( [^\s\]]+)?", text, re.M):
        name, meta = m.group(2), (m.group(3) or "").strip()
        start = m.start(2)
        line_start = text.rfind("\n", 0, start) + 1
        in_usage = text[line_start:start].lstrip().lower().startswith("usage") or \
            text[line_start:start].startswith(" ") and "[" in text[line_start:start]
        if m.group(1) == "[" or in_usage:
            defined.add(name)
            if meta and (meta[0].isupper() or re.fullmatch(r"[A-Za-z0-9]+(\|[A-Za-z0-9]+)+", meta)):
                takes.add(name)
        if meta and re.fullmatch(r"[A-Za-z0-9]+(\|[A-Za-z0-9]+)+", meta):
            values[name] = set(meta.split("|"))
    return defined, mentioned, takes, values


def help_commands(text):
    cmds, inside = [], False
    for line in text.splitlines():
        if re.match(r"^\s*commands:\s*$", line, re.I):
            inside = True
            continue
        if inside:
            m = re.match(r"^\s+([a-z][a-z0-9-]*)(\s{2,}|$)", line)
            if not m:
                break
            cmds.append(m.group(1))
    return cmds


def man_options(path):
    with open(path, encoding="utf-8") as f:
        text = f.read().replace("\\-", "-").replace("\\fB", " ").replace("\\fR", " ") \
            .replace("\\fI", " ").replace("\\fP", " ")
    return set(m.group(2) for m in re.finditer(r"(^|[^A-Za-z0-9-])(" + OPT + ")", text, re.M))


class Shell:
    """One bash with the completion loaded; ask() is one TAB press."""

    def __init__(self, compfile, prog, path, framework):
        self.compfile, self.prog, self.framework = compfile, prog, framework
        self.bindir = os.path.dirname(os.path.abspath(path))
        self.queries = []

    def ask(self, words):
        self.queries.append(words)
        return len(self.queries) - 1

    def run(self):
        def q(s):
            return "'" + s.replace("'", "'\\''") + "'"
        # the program as a user has it: on PATH (a completion may run it)
        lines = ["set +o posix", f"PATH={q(self.bindir)}:$PATH"]
        if self.framework:
            lines.append(f"source {BASH_COMPLETION}")
        lines += [
            f"source {q(self.compfile)} || exit 3",
            f"spec=$(complete -p {q(self.prog)}) || {{ echo 'no complete -p'; exit 4; }}",
            'fn=$(sed -n "s/.* -F \\([^ ]*\\) .*/\\1/p" <<<"$spec")',
            '[ -n "$fn" ] || { echo "not a -F completion: $spec"; exit 5; }',
            "ask() { COMP_WORDS=(\"$@\"); COMP_CWORD=$(($# - 1)); COMP_LINE=\"$*\";",
            "  COMP_POINT=${#COMP_LINE}; COMP_TYPE=9; COMP_KEY=9; COMPREPLY=();",
            "  \"$fn\" \"$1\" \"${COMP_WORDS[COMP_CWORD]}\" \"${COMP_WORDS[COMP_CWORD-1]}\";",
            "  printf '%s\\n' \"${COMPREPLY[@]}\"; echo '@@END@@'; }",
        ]
        for words in self.queries:
            lines.append("ask " + " ".join(q(w) for w in words))
        with tempfile.TemporaryDirectory() as d:
            # what file completion sees: a data set, another file, a directory
            for f in FILES:
                open(os.path.join(d, f), "w").close()
            os.mkdir(os.path.join(d, "sub"))
            p = subprocess.run(["bash", "--norc", "--noprofile", "-c", "\n".join(lines)],
                               capture_output=True, text=True, timeout=60, cwd=d)
        if p.returncode != 0:
            raise SystemExit(f"test_completion: bash with {self.compfile}: exit {p.returncode}: "
                             f"{p.stdout}{p.stderr}")
        out = p.stdout.split("@@END@@\n")
        return [set(x for x in o.split("\n") if x) for o in out[: len(self.queries)]]


def check_program(prog, path, man, compfile, errors):
    top = run_help([path])
    commands = help_commands(top)
    # Reference per context: [] = top level (no commands), or each command.
    contexts = {}
    if commands:
        for c in commands:
            contexts[c] = run_help([path, c])
    else:
        contexts[None] = top
    all_defined = set()
    checks = 0
    for framework in (True, False):
        mode = "with bash-completion" if framework else "alone"
        sh = Shell(compfile, prog, path, framework)
        plan = []
        seen = set()
        first = sh.ask([prog, ""])
        first_dash = sh.ask([prog, "-"])
        for ctx, text in contexts.items():
            defined, mentioned, takes, values = help_options(text)
            all_defined |= defined
            base = [prog] + ([ctx, "x.csv"] if ctx else [])
            opts_q = sh.ask(base + ["-"])
            per = []
            for o in sorted(defined):
                # an option's value handling is checked once per program
                # (the first command that has it)
                if o in ("-h", "--help", "-V", "--version") or o in seen:
                    continue
                seen.add(o)
                per.append((o, o in takes, values.get(o), sh.ask(base + [o, "-" if o not in takes else ""])))
            # a DATA.csv argument completes to CSV files and directories
            files_q = sh.ask(base[:2] + [""]) if ctx and "DATA.csv" in text else None
            plan.append((ctx, defined, mentioned, opts_q, per, files_q))
        res = sh.run()
        where = f"{prog} ({mode})"
        if commands:
            got = res[first]
            cmds_got = set(w for w in got if not w.startswith("-"))
            if cmds_got != set(commands):
                errors.append(f"{where}: commands offered {sorted(cmds_got)}, --help lists {sorted(commands)}")
            top_mentioned = help_options(top)[1]
            extra = set(w for w in got if w.startswith("-")) - top_mentioned
            if extra:
                errors.append(f"{where}: offers {sorted(extra)} at the command position, not in --help")
            checks += 2
        for ctx, defined, mentioned, opts_q, per, files_q in plan:
            label = f"{where} {ctx}" if ctx else where
            if files_q is not None:
                if res[files_q] != {"data.csv", "sub"}:
                    errors.append(f"{label}: DATA.csv completes to {sorted(res[files_q])}, "
                                  "not ['data.csv', 'sub']")
                checks += 1
            got = res[opts_q]
            if not got:
                errors.append(f"{label}: no options offered after '-'")
            missing = defined - got
            if missing:
                errors.append(f"{label}: --help defines {sorted(missing)}, completion does not offer them")
            extra = got - mentioned
            if extra:
                errors.append(f"{label}: completion offers {sorted(extra)}, --help does not mention them")
            checks += 2
            for o, takes_value, vals, q in per:
                got = res[q]
                if takes_value:
                    if any(w.startswith("-") for w in got):
                        errors.append(f"{label}: after {o} (takes a value) options are offered")
                    if vals is not None and got != vals:
                        errors.append(f"{label}: values of {o}: offered {sorted(got)}, --help {sorted(vals)}")
                elif got != res[opts_q]:
                    errors.append(f"{label}: after the flag {o}, '-' completes to {sorted(got)}, "
                                  f"not the options")
                checks += 1
    if man:
        in_man = man_options(man)
        missing = all_defined - in_man
        if missing:
            errors.append(f"{prog}: {man} does not mention {sorted(missing)}")
        checks += 1
    return commands, len(all_defined), checks


def main():
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    compdir = sys.argv[1]
    progs = {}
    for a in sys.argv[2:]:
        name, _, rest = a.partition("=")
        path, _, man = rest.partition(":")
        progs[name] = (path, man or None)
    files = sorted(os.listdir(compdir))
    for f in files:
        if f not in progs:
            R.fail(f"{compdir}/{f}: no such program given (a completion for nothing?)")
    for name, (path, man) in sorted(progs.items()):
        cf = os.path.abspath(os.path.join(compdir, name))
        if not path:
            R.skip(f"{name}: not built by this tree, its completion is not checked")
            continue
        if not os.path.isfile(cf):
            R.fail(f"{name}: no completion file {cf}")
            continue
        errors = []
        cmds, nopts, checks = check_program(name, path, man, cf, errors)
        R.check(not errors, f"{name}: {len(cmds)} commands, {nopts} options, {checks} checks"
                f"{' + man page' if man else ''} (with bash-completion and alone)", "; ".join(errors))
    sys.exit(R.finish())


if __name__ == "__main__":
    main()
