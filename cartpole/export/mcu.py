"""The export's single-precision build for a Cortex-M4F: compiled with ``arm-none-eabi-gcc`` (the strict flags,
:data:`MCU_CFLAGS`), its flash and RAM from ``arm-none-eabi-size`` and its worst stack from GCC's own stack
usage and call graph (``-fstack-usage -fcallgraph-info=su``).

The worst stack is the deepest chain of the export's own functions from ``cp_step`` (or ``cp_reset``), each frame
as GCC reports it (all ``static``: no variable-length arrays, no ``alloca``); calls into libm and libgcc (``sinf``,
the soft-float helpers) are not in the sum, as GCC does not know their frames.
"""
from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path

from cartpole.export.build import STRICT_CFLAGS
from cartpole.export.estimators import ExportError

#: The Cortex-M4F target: Thumb-2, the single-precision FPU, the hard-float ABI, optimised for size.
MCU_CFLAGS = ("-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "-Os")
#: The cross compiler and its size tool.
MCU_CC = "arm-none-eabi-gcc"
MCU_SIZE = "arm-none-eabi-size"

_NODE = re.compile(r'node: \{ title: "([^"]+)" label: "[^"\\]*(?:\\n[^"\\]*)*?\\n(\d+) bytes \(static\)"')
_EDGE = re.compile(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"')


def mcu_tools() -> tuple[str, str] | None:
    """``(gcc, size)`` paths of the ARM toolchain, or None when it is not installed."""
    cc, size = shutil.which(MCU_CC), shutil.which(MCU_SIZE)
    return (cc, size) if cc and size else None


def worst_stack(ci_texts, roots=("cp_step", "cp_reset")) -> tuple[int, list]:
    """The deepest stack (bytes) over the call chains from ``roots`` in GCC's ``.ci`` call graphs, and that
    chain (function names).

    Parameters
    ----------
    ci_texts : sequence of str
        The ``.ci`` files' contents (``-fcallgraph-info=su``).
    roots : sequence of str
        Entry points.

    Returns
    -------
    (int, list of str)
    """
    frame, edges = {}, {}
    for text in ci_texts:
        for title, size in _NODE.findall(text):
            frame[title] = int(size)
        for src, dst in _EDGE.findall(text):
            edges.setdefault(src, set()).add(dst)

    def key(name):  # a function's node title: "file:name" for static functions, "name" otherwise
        return next((t for t in frame if t == name or t.endswith(":" + name)), None)

    best: dict[str, tuple[int, list]] = {}

    def deepest(node, seen):
        if node in best:
            return best[node]
        own = frame.get(node, 0)
        tail = (0, [])
        for nxt in edges.get(node, ()):
            if nxt in seen:
                continue
            cand = deepest(nxt, seen | {nxt})
            if cand[0] > tail[0]:
                tail = cand
        out = (own + tail[0], [node.split(":")[-1]] + tail[1])
        best[node] = out
        return out

    result = (0, [])
    for r in roots:
        k = key(r)
        if k is not None:
            cand = deepest(k, {k})
            if cand[0] > result[0]:
                result = cand
    return result


def cross_build(files: dict) -> dict:
    """Compile an export's files (relative path -> text; its float build) for a Cortex-M4F and measure it.

    Parameters
    ----------
    files : dict
        :func:`cartpole.export.make.export_files` of the design with ``real="float"``.

    Returns
    -------
    dict
        ``target``, ``command`` (the compile line of one source, as run), ``size_command``, ``text``, ``data``,
        ``bss`` (bytes, summed over the library's objects), ``flash`` (text + data), ``ram`` (data + bss),
        ``stack`` (worst stack, bytes), ``stack_chain`` (the functions of that chain).

    Raises
    ------
    ExportError
        No ARM toolchain (install Debian's gcc-arm-none-eabi and libnewlib-arm-none-eabi), or a compile error.
    """
    tools = mcu_tools()
    if tools is None:
        raise ExportError("The Cortex-M4F build needs arm-none-eabi-gcc and arm-none-eabi-size; install Debian's "
                          "gcc-arm-none-eabi and libnewlib-arm-none-eabi (or drop `mcu`).")
    cc, size = tools
    with tempfile.TemporaryDirectory(prefix="cartpole-mcu-") as tmp:
        root = Path(tmp)
        for rel, text in files.items():
            (root / rel).parent.mkdir(parents=True, exist_ok=True)
            (root / rel).write_text(text)
        objs, cis, command = [], [], None
        for src in sorted((root / "src").glob("*.c")):
            obj = root / "build" / (src.stem + ".o")
            obj.parent.mkdir(exist_ok=True)
            cmd = [cc, *STRICT_CFLAGS, *MCU_CFLAGS, "-fstack-usage", "-fcallgraph-info=su", "-Iinclude", "-Isrc",
                   "-c", f"src/{src.name}", "-o", f"build/{obj.name}"]
            proc = subprocess.run(cmd, cwd=root, capture_output=True, text=True, timeout=300, check=False)
            if proc.returncode != 0:
                lines = [ln for ln in proc.stderr.splitlines() if "error" in ln] or ["?"]
                raise ExportError(f"The Cortex-M4F build does not compile: {lines[0].strip()[:160]}; report this "
                                  "as a bug.")
            command = command or " ".join([Path(cc).name, *cmd[1:]])
            objs.append(obj)
            cis.extend(p.read_text() for p in (root / "build").glob(src.stem + "*.ci"))
        out = subprocess.run([size, *[str(o) for o in objs]], capture_output=True, text=True, check=True).stdout
    text = data = bss = 0
    for line in out.splitlines()[1:]:
        parts = line.split()
        text, data, bss = text + int(parts[0]), data + int(parts[1]), bss + int(parts[2])
    stack, chain = worst_stack(cis)
    return {"target": "cortex-m4f", "command": command, "size_command": f"{MCU_SIZE} build/*.o", "text": text,
            "data": data, "bss": bss, "flash": text + data, "ram": data + bss, "stack": stack,
            "stack_chain": chain}
