"""Hostile C for `hybridnav verify` (issue 27): the C never runs in the hybridnav process and
nothing hangs. Without --trust only an unmodified export is compiled (refused before compiling
otherwise); with --trust the C runs, but in a child process with a time limit; includes that read
other files are refused, and no compiler message quotes another file."""

from __future__ import annotations

import os
import re
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_fuzzy_export_fuzz import mutated

from hybridnav import HybridnavError, fuzzy
from hybridnav.cli import main
from hybridnav.fuzzy.export import export, to_c
from hybridnav.fuzzy.export.c import SYSTEM_MARK, embedded_system
from hybridnav.fuzzy.export.sandbox import CHILD_CPU_SECONDS, check_includes
from hybridnav.fuzzy.export.sil import CompiledFIS

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None and shutil.which("cc") is None,
                                reason="no C compiler")

SYSTEM = "effc-2rule"
REFUSED = r"expected the file hybridnav exports for the system embedded in {}, unmodified"
#: what a hostile file points the preprocessor at (a stand-in for /etc/passwd)
SECRET = "root:x:0:0:SECRET-LINE:/root:/bin/sh\n" * 20


def _export(folder: Path, stem: str, change=lambda src: src) -> Path:
    """The export of SYSTEM as ``folder/stem.c`` (and ``.h``), its source passed through
    ``change``."""
    code = to_c(fuzzy.builtin(SYSTEM), stem)
    (folder / f"{stem}.h").write_text(code.header)
    (folder / f"{stem}.c").write_text(change(code.source))
    return folder / f"{stem}.c"


def _with_code(extra: str):
    """A change that appends ``extra`` (C) to the source."""
    head = "\n#include <stdio.h>\n#include <stdlib.h>\n#include <unistd.h>\n"
    return lambda src: src + head + extra


def _before_evaluate(stmt: str):
    """A change that runs ``stmt`` at the start of ``<p>_evaluate`` (with <stdlib.h>)."""
    def change(src: str) -> str:
        m = re.search(r"(\w+_evaluate\(const \w+ in\[\w+\]\)\n\{\n)", src)
        return "#include <stdlib.h>\n" + src[:m.end()] + f"    {stmt}\n" + src[m.end():]
    return change


def _verify(c_file: Path, *extra: str) -> int:
    return main(["verify", SYSTEM, str(c_file), "--scenarios", "effc-env-a", *extra])


def test_a_genuine_export_is_compiled_and_evaluates_like_python(tmp_path):
    fs = fuzzy.builtin(SYSTEM)
    export(fs, "c", tmp_path / "effc")
    with CompiledFIS(tmp_path / "effc.c") as compiled:
        assert compiled.system == fs
        d, a = np.meshgrid(np.linspace(-0.5, 3.5, 9), np.linspace(-0.2, 2.0, 7))
        np.testing.assert_allclose(compiled.evaluate(dtheta=d, alpha=a),
                                   fs.evaluate(dtheta=d, alpha=a), rtol=0, atol=1e-12)
        big = np.linspace(0, 3, 10_000)              # more than one exchange (4096 a call)
        np.testing.assert_allclose(compiled.evaluate(dtheta=big, alpha=0.5),
                                   fs.evaluate(dtheta=big, alpha=0.5), rtol=0, atol=1e-12)
    with pytest.raises(HybridnavError, match="the child process was closed"):
        compiled.evaluate(dtheta=0.1, alpha=0.2)
    # line endings converted (a checkout on Windows) are still the export
    for f in ("effc.c", "effc.h"):
        (tmp_path / f).write_bytes((tmp_path / f).read_bytes().replace(b"\n", b"\r\n"))
    CompiledFIS(tmp_path / "effc.c").close()


def test_a_constructor_is_refused_before_compiling_and_runs_only_in_the_child(tmp_path, capsys,
                                                                              monkeypatch):
    marker = tmp_path / "MARKER"
    c = _export(tmp_path, "ctor", _with_code(
        "#include <sys/resource.h>\n"
        "__attribute__((constructor)) static void evil(void)\n"
        "{ struct rlimit cpu, mem; FILE *f;\n"
        "  getrlimit(RLIMIT_CPU, &cpu); getrlimit(RLIMIT_AS, &mem);\n"
        f"  f = fopen(\"{marker}\", \"w\");\n"
        "  fprintf(f, \"%d %ld %ld\", (int)getpid(), (long)cpu.rlim_cur, (long)mem.rlim_cur);\n"
        "  fclose(f); }\n"))
    monkeypatch.setenv("CC", "/no/such/compiler")           # refused before any compiler runs
    assert _verify(c) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"hybridnav: error: {c}: " + REFUSED.format("ctor.c")) and \
        "--trust" in err and "Traceback" not in err
    assert not marker.exists()
    monkeypatch.delenv("CC")
    assert _verify(c, "--trust") == 0                        # it evaluates like the export
    assert "verified" in capsys.readouterr().out
    pid, cpu, memory = map(int, marker.read_text().split())
    assert pid != os.getpid()                                # it ran, in another process
    assert cpu == CHILD_CPU_SECONDS and memory == 2**30       # with limits


def test_an_endless_loop_ends_in_an_error_within_the_time_limit(tmp_path, capsys):
    c = _export(tmp_path, "loop", _before_evaluate("for (;;) {}"))
    assert _verify(c) == 2                                   # not an export: refused
    capsys.readouterr()
    t0 = time.monotonic()
    assert _verify(c, "--trust", "--timeout", "0.5") == 2
    assert time.monotonic() - t0 < 30        # the closed loop's imports, one compile, 0.5 s
    err = capsys.readouterr().err
    assert err == (f"hybridnav: error: {c}: evaluate did not return within 0.5 s (the time "
                   "limit): its child process was killed\n")


def test_a_hanging_constructor_a_crash_and_an_exit_are_reported(tmp_path):
    c = _export(tmp_path, "hang", _with_code(
        "__attribute__((constructor)) static void hang(void) { for (;;) {} }\n"))
    with pytest.raises(HybridnavError, match=r"hang\.c: the compiled program's start did not "
                                             r"return within 0\.3 s \(the time limit\)"):
        CompiledFIS(c, trust=True, timeout=0.3)
    c = _export(tmp_path, "crash", _before_evaluate("*(volatile int *)0 = 1;"))
    compiled = CompiledFIS(c, trust=True)
    with pytest.raises(HybridnavError, match=r"crash\.c: evaluate crashed with signal SIGSEGV in "
                                             r"its child process\Z"):
        compiled.evaluate(dtheta=0.1, alpha=0.2)
    with pytest.raises(HybridnavError, match="SIGSEGV"):    # and stays failed
        compiled.evaluate(dtheta=0.1, alpha=0.2)
    c = _export(tmp_path, "quit", _before_evaluate("exit(7);"))
    with pytest.raises(HybridnavError, match=r"quit\.c: evaluate: its child process exited with "
                                             r"status 7 instead of answering\Z"):
        CompiledFIS(c, trust=True, timeout=5).evaluate(dtheta=0.1, alpha=0.2)


@pytest.mark.parametrize("target", ["secret", "/dev/stdin"])
@pytest.mark.parametrize("trust", [False, True])
def test_including_another_file_is_refused_fast_and_quotes_nothing(tmp_path, capsys, target,
                                                                   trust):
    secret = tmp_path / "passwd"
    secret.write_text(SECRET)
    name = str(secret) if target == "secret" else target
    c = _export(tmp_path, "inc", lambda src: f'#include "{name}"\n' + src)
    t0 = time.monotonic()
    assert _verify(c, *(["--trust"] if trust else [])) == 2
    assert time.monotonic() - t0 < 10
    err = capsys.readouterr().err
    assert "SECRET" not in err and name not in err and "Traceback" not in err
    if trust:
        assert err == (f"hybridnav: error: {c}: line 1: #include: expected a header named "
                       "relative to the file or the system's include folders (\"name.h\" or "
                       "<name.h>), got an absolute path; nothing was compiled\n")
    else:
        assert REFUSED.format("inc.c") in err and "at line 1;" in err


@pytest.mark.parametrize("text, problem", [
    ('#include "/etc/passwd"', "an absolute path"),
    ("#include </etc/passwd>", "an absolute path"),
    ('#include "../../etc/passwd"', "a '..' component"),
    ("#  include_next <a/../../b.h>", "a '..' component"),
    ('#define F "/etc/passwd"\n#include F', "a computed (macro) or malformed name"),
    ('#/* a comment */include "/etc/passwd"', "an absolute path"),
    ('#inc\\\nlude "/etc/passwd"', "an absolute path"),
    ('#include \\   \n"/dev/stdin"', "an absolute path"),
    ('??=include "/etc/passwd"', "an absolute path"),
    ('%:include "/etc/passwd"', "an absolute path"),
    ('#include "??/\n/etc/passwd"', "an absolute path"),
    ('#embed "/dev/zero"', "an absolute path"),
    ('#import "~/x.h"', "an absolute path"),
    ('#include ""', "an empty name"),
])
def test_includes_are_read_as_the_preprocessor_reads_them(text, problem):
    line = 1 + ("define" in text)
    with pytest.raises(HybridnavError, match=rf"^f\.c: line {line}: #\w+: expected a header "
                                             rf"named .* got {re.escape(problem)}; nothing was "
                                             r"compiled\Z"):
        check_includes(text + "\nint b;\n", "f.c")


def test_includes_an_export_or_a_program_may_use_pass():
    check_includes('#include <stdint.h>\n#include "effc.h"\n#include <sys/types.h>\n'
                   '/* #include "/etc/passwd" */\n// #include "/etc/passwd"\n'
                   'const char *s = "#include \\"/etc/passwd\\"";\n'
                   "char q = '\"'; /* a quote char does not hide what follows */\n", "f.c")
    with pytest.raises(HybridnavError, match="line 2: #include"):
        # an unterminated quote ends with its line: it does not hide the next one
        check_includes("#error don't\n#include \"/etc/passwd\"\n// '\n", "f.c")
    with pytest.raises(HybridnavError, match="line 5: #include"):
        check_includes("/* a\n b\n */ int x; \\\n\n#include \"/x\"\n", "f.c")


def test_a_compiler_message_quotes_nothing_of_the_file_it_names(tmp_path):
    secret = tmp_path / "passwd"
    secret.write_text(SECRET)
    # #line makes the compiler name (and, showing a caret, print) another file
    c = _export(tmp_path, "line", lambda src: f'#line 1 "{secret}"\nroot:x:0:0;\n' + src)
    with pytest.raises(HybridnavError) as exc:
        CompiledFIS(c, trust=True)
    msg = str(exc.value)
    assert msg == (f"{c}: does not compile: an error at line 1 of {secret} (a file it includes "
                   "or names)")
    assert "SECRET" not in msg and "root:x" not in msg and len(msg) < 600
    # an error in the file itself: its location and kind; what it quotes is cut
    c = _export(tmp_path, "own", lambda src: src + "\nroot:x:0:0:SECRET;\n")
    with pytest.raises(HybridnavError, match=rf"^{re.escape(str(c))}: does not compile: "
                                             rf"{re.escape(str(c))}:\d+:\d+: .*'\.\.\.'") as exc:
        CompiledFIS(c, trust=True)
    assert "SECRET" not in str(exc.value) and "root:x" not in str(exc.value)


def test_a_modified_export_is_refused_without_trust(tmp_path, monkeypatch):
    fs = fuzzy.builtin(SYSTEM)
    first = {}

    def change(src: str) -> str:                  # one table constant changed
        m = re.search(r"K\(0\.5\)", src)
        first["line"] = src.count("\n", 0, m.start()) + 1
        return src[:m.start()] + "K(0.6)" + src[m.end():]
    c = _export(tmp_path, "mod", change)
    with pytest.raises(HybridnavError, match=rf"^{re.escape(str(c))}: "
                                             + REFUSED.format(r"mod\.c") +
                                             rf", got one that differs from it at line "
                                             rf"{first['line']}; export it again .* --trust"):
        CompiledFIS(c)
    # an edited header is refused as well, naming the header
    c = _export(tmp_path, "hdr")
    h = c.with_suffix(".h")
    h.write_text(h.read_text().replace("#define HDR_N_INPUTS 2", "#define HDR_N_INPUTS 2\n"
                                                                 "#include \"evil.h\""))
    with pytest.raises(HybridnavError, match=rf"^{re.escape(str(h))}: expected the file"):
        CompiledFIS(c)
    # trusted, the modified one compiles and gives other numbers
    with CompiledFIS(tmp_path / "mod.c", trust=True) as compiled:
        assert compiled.system is None
        d = np.linspace(0, 3, 50)
        assert np.max(np.abs(compiled.evaluate(dtheta=d, alpha=0.5)
                             - fs.evaluate(dtheta=d, alpha=0.5))) > 0


def test_a_pipe_or_a_missing_header_is_refused_without_reading(tmp_path):
    os.mkfifo(tmp_path / "fifo.c")
    (tmp_path / "fifo.h").write_text("/* */\n")
    with pytest.raises(HybridnavError, match=r"fifo\.c: expected the C source as a regular file"):
        CompiledFIS(tmp_path / "fifo.c")
    (tmp_path / "alone.c").write_text("int x;\n")
    with pytest.raises(HybridnavError, match=r"alone\.h: no such file"):
        CompiledFIS(tmp_path / "alone.c")
    with pytest.raises(HybridnavError, match=r"timeout: expected a number of seconds in \(0, 86400\]"):
        CompiledFIS(tmp_path / "alone.c", timeout=0)


def test_a_compiler_that_hangs_is_killed_with_what_it_started(tmp_path, monkeypatch):
    pidfile = tmp_path / "pid"
    cc = tmp_path / "slowcc"
    cc.write_text(f"#!/bin/sh\nsleep 60 &\necho $! > {pidfile}\nwait\n")
    cc.chmod(0o755)
    c = _export(tmp_path, "effc")
    monkeypatch.setenv("CC", str(cc))
    t0 = time.monotonic()
    with pytest.raises(HybridnavError, match=r"effc\.c: expected to compile within 1 s, took "
                                             r"longer \(the compiler was stopped\)"):
        CompiledFIS(c, compile_timeout=1)
    assert time.monotonic() - t0 < 10
    stat = Path(f"/proc/{int(pidfile.read_text())}/stat")
    for _ in range(100):                     # SIGKILLed with its group: gone, or a zombie
        if not stat.exists() or stat.read_text().rsplit(")", 1)[1].split()[0] == "Z":
            break
        time.sleep(0.05)
    else:
        raise AssertionError("the compiler's child process still runs")


def _another_export(text: str, which: str, code) -> bool:
    """Whether a mutated file is, byte for byte, what hybridnav writes for the system embedded
    in it (a change to the embedded system that touches only what the code does not use, e.g.
    a rule's description: an unmodified export of another system, which verify may compile)."""
    source = text if which == "source" else code.source
    try:
        system = embedded_system(source.replace("\r\n", "\n"), "m.c")
    except HybridnavError:
        return False
    if system is None:
        return False
    again = to_c(system, "m")
    return (again.source, again.header) == (source.replace("\r\n", "\n"),
                                            (text if which == "header" else code.header)
                                            .replace("\r\n", "\n"))


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                 HealthCheck.data_too_large])
@given(data=st.data())
def test_any_change_to_an_export_is_refused_before_compiling(tmp_path, monkeypatch, data):
    code = to_c(fuzzy.builtin(SYSTEM), "m")
    which = data.draw(st.sampled_from(["source", "header"]))
    text = data.draw(mutated([code.source if which == "source" else code.header]))
    original = code.source if which == "source" else code.header
    (tmp_path / "m.c").write_text(text if which == "source" else code.source, encoding="utf-8",
                                  errors="surrogatepass")
    (tmp_path / "m.h").write_text(text if which == "header" else code.header, encoding="utf-8",
                                  errors="surrogatepass")
    monkeypatch.setenv("CC", "/no/such/compiler")
    with pytest.raises(HybridnavError) as exc:
        CompiledFIS(tmp_path / "m.c")
    if text.replace("\r\n", "\n") != original and not _another_export(text, which, code):
        assert "no C compiler" not in str(exc.value), "a changed export reached the compiler"
    assert len(str(exc.value)) < 800


@settings(max_examples=60, deadline=None)
@given(description=st.text(st.characters(), max_size=300),
       name=st.text(st.characters(blacklist_categories=("Cs",)), min_size=1, max_size=40))
def test_the_embedded_system_travels_exactly_and_stays_a_comment(description, name):
    d = fuzzy.builtin(SYSTEM).to_dict()
    d.update(name=name if name.strip() else "x", description=description)
    try:
        fs = fuzzy.FuzzySystem.from_dict(d)
    except HybridnavError:                 # a name or description the system refuses
        return
    code = to_c(fs, "m")
    block = code.source[code.source.index(SYSTEM_MARK):]
    assert block.count("*/") == 1 and block.endswith(" */\n") and "/*" not in block[2:]
    assert "??/" not in block and not re.search(r"[ \\]\n", block)
    assert embedded_system(code.source, "m.c") == fs


def test_run_with_an_edited_c_file_is_refused_too(tmp_path, capsys):
    c = _export(tmp_path, "effc", _before_evaluate("for (;;) {}"))
    assert main(["run", "effc-env-a", "--planner", "effc", "--fis", str(c),
                 "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert f"{c}: " + REFUSED.format("effc.c") in err and "Traceback" not in err
    assert not (tmp_path / "run").exists()


def test_an_embedded_system_far_larger_than_the_file_is_refused_without_generating_it(
        tmp_path, monkeypatch):
    from hybridnav.fuzzy.export import c as c_module

    d = fuzzy.builtin(SYSTEM).to_dict()
    for v in (*d["inputs"], d["output"]):
        v["points"] = 50_001                   # tables of ~6 MB in a file of 0.1 MB
    big = c_module._system_comment(fuzzy.FuzzySystem.from_dict(d))
    c = _export(tmp_path, "big", lambda src: src[:src.index(SYSTEM_MARK) - 1] + big)
    monkeypatch.setattr(sys.modules[CompiledFIS.__module__], "to_c", None)   # never called
    with pytest.raises(HybridnavError, match=r"big\.c: expected the file hybridnav exports for "
                                             r"the system embedded in big\.c, got one too short "
                                             r"for its tables; pass --trust"):
        CompiledFIS(c)


def test_what_trusted_c_prints_does_not_reach_the_replies(tmp_path, capfd):
    fs = fuzzy.builtin(SYSTEM)
    noisy = _before_evaluate('printf("noise\\n"); fflush(stdout); fputs("err\\n", stderr);')
    c = _export(tmp_path, "noisy", lambda src: "#include <stdio.h>\n" + noisy(src))
    with CompiledFIS(c, trust=True) as compiled:
        d = np.linspace(0, 3, 20)
        np.testing.assert_allclose(compiled.evaluate(dtheta=d, alpha=0.5),
                                   fs.evaluate(dtheta=d, alpha=0.5), rtol=0, atol=1e-12)
    out, err = capfd.readouterr()
    assert "noise" not in out and "err" not in err


def test_verify_takes_the_deployment_settings_and_explains_a_parted_loop(tmp_path, capsys):
    from hybridnav.cli import main

    assert main(["export", "effc-tuned", "--format", "c", "-o", str(tmp_path / "effc")]) == 0
    capsys.readouterr()
    code = main(["verify", "effc-tuned", str(tmp_path / "effc.c"), "--set", "safety_margin=0.05",
                 "--scenarios", "effc-train-2,effc-env-b"])
    out = capsys.readouterr().out
    assert code == 0 and "planner effc, safety_margin=0.05, seed 0:" in out
    assert main(["verify", "effc-tuned", str(tmp_path / "effc.c"), "--set", "nosuch=1"]) == 2
    assert "planner effc: unknown parameter 'nosuch'" in capsys.readouterr().err


def test_a_changed_rule_description_is_an_export_of_another_system(tmp_path, monkeypatch):
    """Found by the fuzz test above: a rule description lives only in the embedded system, so
    changing it gives exactly the export hybridnav writes for the changed system; verify may
    compile that (it is generated code), and the fuzz test's oracle now knows it."""
    code = to_c(fuzzy.builtin(SYSTEM), "m")
    i = code.source.index('"description":"', code.source.index('"rules"'))
    text = code.source[:i + 15] + "X" + code.source[i + 16:]
    assert _another_export(text, "source", code)
    (tmp_path / "m.c").write_text(text)
    (tmp_path / "m.h").write_text(code.header)
    monkeypatch.setenv("CC", "/no/such/compiler")
    with pytest.raises(HybridnavError, match="no C compiler"):
        CompiledFIS(tmp_path / "m.c")
    edited = text.replace("M_K(0.5)", "M_K(0.6)", 1)          # code edited: refused before
    assert not _another_export(edited, "source", code)
    (tmp_path / "m.c").write_text(edited)
    with pytest.raises(HybridnavError) as exc:
        CompiledFIS(tmp_path / "m.c")
    assert "no C compiler" not in str(exc.value)
