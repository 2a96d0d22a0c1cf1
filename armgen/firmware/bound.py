"""A static worst-case bound on the instructions a function of a cross-compiled image executes
(issue 42): counted from the object code, not measured. docs/targets.md, "Static bound",
states what it assumes and compares it with QEMU's counts.

For each function: its basic blocks from the disassembly (``objdump -d``), the control-flow
graph (jump tables read from the image), its natural loops (back edges to a dominating
header). A loop's count comes from its C source: the DWARF line (``-g``; every armgen build
has it) of its back or exit branch is a ``for (i = 0; i < BOUND; ++i)`` and the build's own
preprocessor (or compiler, for ``sizeof``) evaluates BOUND; a BOUND that is a parameter of an
inlined function takes the argument of its call site. Besides: gcc's inline copies (memcpy of
N bytes: N / 4 turns), bit-clearing loops (32 turns), a caller's stop (the generated IK's step
loop runs at most ``max_iterations`` steps: ``loop_caps``), a bisection over a stated range
(``search_ranges``), and in library code without source a down-counter read from the object
code or a count stated in LIBRARY_LOOPS. A loop the compiler unrolled turns fewer times than
its source loop: the source's count stays a bound.

The bound of a function is the longest path through its graph from the entry to a return,
every instruction of a block counted (a predicated instruction of an IT block counts: it
executes as a no-op), each loop collapsed, innermost first, into one node costing

    (header runs - 1) × (the longest turn) + (the longest way from the header out of it)

where the header runs at most BOUND + 1 times when the loop may leave from its header (tested
at the top) and BOUND times otherwise (rotated: tested at the bottom), and each call (``bl``,
``jal``, a tail call's branch) costs its callee's bound; memset/memcpy/memmove of a constant
size n cost their straight path plus n times their longest turn. Blocks that call a function
of ``avoid`` are no path (one controller mode's tick: the other modes' tick functions, the
MOVE_TO planner). A recursive call, an indirect call or jump, or a loop without a count is an
error (BoundError naming the function, the address and the line): there is no silent guess.

The bound counts instructions, the unit QEMU's ``-icount`` measures. ``block_cost`` turns it
into a cycle bound under stated assumptions: CortexM4Cycles (flash wait states),
CortexM0PlusCycles.
"""

from __future__ import annotations

import math
import re
import subprocess
import tempfile
from collections import Counter, defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from .errors import FirmwareError
from .sources import FIRMWARE_DIR
from .targets import Target


class BoundError(FirmwareError):
    """The object code holds something the static bound cannot count."""


@dataclass(frozen=True)
class Instruction:
    address: int
    size: int
    mnemonic: str
    operands: str
    target: int | None  # the branch's or call's destination
    words: tuple[int, ...] = ()  # a data directive's values (.word/.short/.byte): jump tables


@dataclass
class Function:
    name: str
    start: int
    instructions: list[Instruction] = field(default_factory=list)


_LINE = re.compile(r"^\s*([0-9a-f]+):\t((?:[0-9a-f]{2,8} ?)+)\s*\t(\S+)\s*(.*)$")
_HEAD = re.compile(r"^([0-9a-f]+) <([^>]+)>:$")
_TARGET = re.compile(r"(?:^|[\s,(])(?:0x)?([0-9a-f]+) <([^>+]+)(?:\+0x[0-9a-f]+)?>")


def disassemble(objdump: str, elf: Path) -> dict[int, Function]:
    """Every function of ``elf``'s text, by address (static functions of two sources may
    share a name)."""
    text = subprocess.run([objdump, "-d", "-j", ".text", str(elf)], capture_output=True, text=True, check=True).stdout
    functions: dict[int, Function] = {}
    current: Function | None = None
    for line in text.splitlines():
        head = _HEAD.match(line)
        if head:
            current = Function(head.group(2), int(head.group(1), 16))
            functions[current.start] = current
            continue
        m = _LINE.match(line)
        if not m or current is None:
            continue
        raw = m.group(2).split()
        size = sum(len(h) // 2 for h in raw)
        operands = m.group(4).split("@")[0].split(";")[0].strip()  # no comment
        mnemonic = m.group(3)
        words: tuple[int, ...] = ()
        if mnemonic.startswith("."):  # literal pool or jump table: little-endian bytes
            words = tuple(int(h, 16) for h in raw)
        target = _TARGET.search(m.group(4))
        current.instructions.append(Instruction(int(m.group(1), 16), size, mnemonic, operands,
                                                int(target.group(1), 16) if target else None, words))
    return {a: f for a, f in functions.items() if f.instructions}


# What an instruction does to the control flow.
SEQ, BRANCH, CBRANCH, CALL, RETURN, CRETURN, TABLE, STOP = "seq", "b", "cb", "call", "ret", "cret", "table", "stop"

_ARM_COND = "eq|ne|cs|cc|hs|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le"
_ARM_B = re.compile(rf"^b({_ARM_COND})?(\.n|\.w)?$")


def _writes_pc_from_memory(base: str, operands: str) -> bool:
    """pop {..., pc}, ldmia sp!, {..., pc}, ldr pc, [sp], #4: a return."""
    if base.startswith(("pop", "ldm")):
        return bool(re.search(r"\{[^}]*\bpc\}", operands))
    return base.startswith("ldr") and operands.startswith("pc,")


class Memory:
    """The bytes of an image's loaded sections (``objdump -s``): jump tables and their literals."""

    def __init__(self, objdump: str, elf: Path):
        text = subprocess.run([objdump, "-s", str(elf)], capture_output=True, text=True, check=True).stdout
        self.bytes: dict[int, int] = {}
        loaded = True
        for m in re.finditer(r"^Contents of section (\S+):$|^ ([0-9a-f]+) ((?:[0-9a-f]{2,8} ){1,4})", text, re.M):
            if m.group(1):  # the debug and attribute sections are not loaded (their addresses start at 0)
                loaded = not m.group(1).startswith((".debug", ".comment", ".ARM.attributes", ".riscv.attributes"))
                continue
            if not loaded:
                continue
            address = int(m.group(2), 16)
            for b in bytes.fromhex(m.group(3).replace(" ", "")):
                self.bytes[address] = b
                address += 1

    def word(self, address: int) -> int:
        try:
            return int.from_bytes(bytes(self.bytes[address + k] for k in range(4)), "little")
        except KeyError:
            raise BoundError(f"no data at {address:#x} in the image (a jump table's entry)") from None


class ArmIsa:
    """Thumb-2 / Thumb (Armv6-M, Armv7-M, Armv8-M)."""

    def __init__(self, memory: Memory | None = None):
        self._it_left = 0
        self.memory = memory

    def classify(self, ins: Instruction) -> str:
        conditional = self._it_left > 0
        if conditional:
            self._it_left -= 1
        mn = ins.mnemonic
        if mn.startswith("it") and re.fullmatch(r"it[te]{0,3}", mn):
            self._it_left = len(mn) - 1
            return SEQ
        if mn.startswith("."):
            return STOP  # data: never reached by a fall-through in code gcc emits
        base = re.sub(rf"({_ARM_COND})(?=(\.n|\.w)?$)", "", mn) if conditional else mn
        b = _ARM_B.match(mn)
        if b:
            return CBRANCH if (b.group(1) or conditional) else BRANCH
        if mn in ("cbz", "cbnz"):
            return CBRANCH
        if base in ("bl", "bl.w"):
            return CALL
        if base in ("blx", "bx") and ins.operands != "lr":
            raise BoundError(f"an indirect {'call' if base == 'blx' else 'jump'} at {ins.address:#x} ({mn} {ins.operands})")
        if base == "bx" or _writes_pc_from_memory(base, ins.operands):
            return CRETURN if conditional else RETURN
        if base in ("tbb", "tbh"):
            return TABLE
        if base in ("udf", "bkpt"):
            return STOP
        if base == "mov" and re.fullmatch(r"pc,\s*r\d+", ins.operands) and not conditional:
            return TABLE  # Thumb-1's switch: a table of addresses loaded, then moved into pc
        if re.search(r"\bpc\b", ins.operands.split(",")[0]) and not base.startswith(("str", "cmp", "tst", "push")):
            raise BoundError(f"an instruction writing pc at {ins.address:#x} ({mn} {ins.operands})")
        return SEQ

    @staticmethod
    def _range(fn: Function, index: int, reg: str) -> int:
        """The entries a table indexed by ``reg`` has: the `cmp reg, #K` before it allows K + 1."""
        for prev in reversed(fn.instructions[max(0, index - 8):index]):
            m = re.fullmatch(rf"{reg},\s*#(\d+)", prev.operands)
            if prev.mnemonic.startswith("cmp") and m:
                return int(m.group(1)) + 1
        raise BoundError(f"{fn.name}: the jump table at {fn.instructions[index].address:#x} has no range check "
                         "before it")

    def table_targets(self, fn: Function, index: int) -> list[int]:
        """The destinations of the tbb/tbh (or Thumb-1's `mov pc, rT`) at fn.instructions[index]."""
        ins = fn.instructions[index]
        if ins.mnemonic == "mov":
            return self._address_table(fn, index)
        reg = re.search(r"\b(r\d+|sl|fp|ip|sb|lr)\b", ins.operands.split(",", 1)[1]).group(1)
        count = self._range(fn, index, reg)
        data = bytearray()
        for d in fn.instructions[index + 1:]:
            if not d.mnemonic.startswith("."):
                break
            for w, width in zip(d.words, [d.size // len(d.words)] * len(d.words)):
                data += w.to_bytes(width, "little")
        step = 1 if ins.mnemonic == "tbb" else 2
        base = ins.address + 4
        return [base + 2 * int.from_bytes(data[k * step:(k + 1) * step], "little") for k in range(count)]

    def _address_table(self, fn: Function, index: int) -> list[int]:
        """ldr rA, [pc, #n] (the table's address); lsls rI, rI, #2; ldr rT, [rA, rI]; mov pc, rT."""
        ins = fn.instructions[index]
        target_reg = ins.operands.split(",")[1].strip()
        window = fn.instructions[max(0, index - 4):index]
        load = next((i for i in reversed(window) if i.mnemonic == "ldr"
                     and re.fullmatch(rf"{target_reg},\s*\[(r\d+),\s*(r\d+)\]", i.operands)), None)
        if load is None or self.memory is None:
            raise BoundError(f"{fn.name}: an indirect jump at {ins.address:#x} (mov pc, {target_reg})")
        base_reg, index_reg = re.fullmatch(r"\w+,\s*\[(r\d+),\s*(r\d+)\]", load.operands).groups()
        literal = next((i for i in reversed(window) if i.mnemonic == "ldr" and i.operands.startswith(f"{base_reg}, [pc")
                        and i.target is not None), None)
        if literal is None:
            raise BoundError(f"{fn.name}: the jump table at {ins.address:#x} has no literal address")
        table = self.memory.word(literal.target)
        count = self._range(fn, index, index_reg)
        return [self.memory.word(table + 4 * k) & ~1 for k in range(count)]


class RiscvIsa:
    """RV32 (objdump's aliases: j, jal, ret, beqz ...)."""

    CONDITIONAL = {"beq", "bne", "blt", "bge", "bltu", "bgeu", "beqz", "bnez", "blez", "bgez", "bltz", "bgtz",
                   "bgt", "ble", "bgtu", "bleu"}

    def classify(self, ins: Instruction) -> str:
        mn, ops = ins.mnemonic, ins.operands
        if mn.startswith("."):
            return STOP
        if mn in self.CONDITIONAL:
            return CBRANCH
        if mn == "j" or (mn == "jal" and ops.startswith("zero,")):
            return BRANCH
        if mn == "jal":
            return CALL
        # t0 (jr t0): the link of the save/restore millicode, which is called with jal t0
        if mn == "ret" or (mn == "jr" and ops in ("ra", "t0")) or (mn == "jalr" and re.fullmatch(r"zero,\s*0?\(?ra\)?(,\s*0)?", ops)):
            return RETURN
        if mn in ("jr", "jalr"):
            raise BoundError(f"an indirect {'call' if mn == 'jalr' else 'jump'} at {ins.address:#x} ({mn} {ops})")
        if mn in ("ebreak", "unimp"):
            return STOP
        return SEQ

    def table_targets(self, fn: Function, index: int) -> list[int]:  # no tables: jr raises first
        raise BoundError(f"{fn.name}: a jump table at {fn.instructions[index].address:#x}")


@dataclass
class Block:
    start: int
    instructions: list[Instruction]
    calls: list[int]  # destinations of the calls it makes (a tail call included)
    successors: list[int]  # block starts in the same function
    returns: bool  # the function may return from its end


def blocks_of(fn: Function, isa) -> dict[int, Block]:
    """The basic blocks of ``fn``: control flow splits blocks, calls do not."""
    inside = {ins.address for ins in fn.instructions}
    # Thumb-1 code (Armv6-M) jumps beyond a b's 2 KB within a function with bl: a branch there
    kinds = [BRANCH if kind == CALL and ins.target in inside else kind
             for ins, kind in ((i, isa.classify(i)) for i in fn.instructions)]
    leaders = {fn.start}
    tables: dict[int, list[int]] = {}
    for k, (ins, kind) in enumerate(zip(fn.instructions, kinds)):
        if kind in (BRANCH, CBRANCH) and ins.target in inside:
            leaders.add(ins.target)
        if kind == TABLE:
            tables[k] = isa.table_targets(fn, k)
            leaders.update(tables[k])
        if kind in (BRANCH, CBRANCH, RETURN, CRETURN, TABLE, STOP) and k + 1 < len(fn.instructions):
            leaders.add(fn.instructions[k + 1].address)
    blocks: dict[int, Block] = {}
    current: Block | None = None
    for k, (ins, kind) in enumerate(zip(fn.instructions, kinds)):
        if ins.address in leaders:
            if current is not None and not current.returns and current.successors == [] and _falls(current):
                current.successors.append(ins.address)
            current = Block(ins.address, [], [], [], False)
            blocks[ins.address] = current
        if ins.mnemonic.startswith("."):
            current.instructions.append(ins)
            continue
        current.instructions.append(ins)
        nxt = fn.instructions[k + 1].address if k + 1 < len(fn.instructions) else None
        if kind == CALL:
            current.calls.append(ins.target)
        elif kind in (BRANCH, CBRANCH):
            if ins.target in inside:
                current.successors.append(ins.target)
            else:  # a tail call: the callee returns for this function
                current.calls.append(ins.target)
                current.returns = True
            if kind == CBRANCH and nxt is not None:
                current.successors.append(nxt)
        elif kind == RETURN:
            current.returns = True
        elif kind == CRETURN:
            current.returns = True
            if nxt is not None:
                current.successors.append(nxt)
        elif kind == TABLE:
            current.successors.extend(dict.fromkeys(tables[k]))
    for b in blocks.values():
        b.instructions = [i for i in b.instructions if not i.mnemonic.startswith(".")]
    return {a: b for a, b in blocks.items() if b.instructions}


def _falls(block: Block) -> bool:
    """Whether the block's end falls through into the next one (it ends in no jump)."""
    last = block.instructions[-1]
    return not last.mnemonic.startswith(".") and not _ARM_B.match(last.mnemonic) and last.mnemonic not in (
        "j", "tbb", "tbh", "udf", "bkpt", "ebreak", "unimp")


def dominators(entry: int, succ: dict[int, list[int]]) -> dict[int, set[int]]:
    nodes = list(succ)
    preds: dict[int, list[int]] = defaultdict(list)
    for a, ss in succ.items():
        for s in ss:
            preds[s].append(a)
    dom = {n: set(nodes) for n in nodes}
    dom[entry] = {entry}
    changed = True
    while changed:
        changed = False
        for n in nodes:
            if n == entry:
                continue
            ps = [dom[p] for p in preds[n] if p in dom]
            new = set.intersection(*ps) | {n} if ps else {n}
            if new != dom[n]:
                dom[n], changed = new, True
    return dom


def reachable(entry: int, succ: dict[int, list[int]]) -> set[int]:
    seen, todo = {entry}, [entry]
    while todo:
        for s in succ[todo.pop()]:
            if s not in seen:
                seen.add(s)
                todo.append(s)
    return seen


# for (i = START; i < BOUND; ++i): START 0, or the counter of an enclosing such loop (>= 0), so
# the body runs at most BOUND times (BOUND + 1 with <=).
_FOR = re.compile(r"for\s*\(\s*(?:\w+\s+)?(\w+)\s*=\s*(0[uU]?|\w+)\s*;\s*(\w+)\s*(<=|<)\s*([^;]+?)\s*;\s*"
                  r"(?:\+\+\s*(\w+)|(\w+)\s*\+\+)\s*\)")
# for (b = x; b != 0u; b &= b - 1u): clears the lowest set bit each turn
_BITS = re.compile(r"for\s*\(\s*(\w+)\s*=[^;]+;\s*(\w+)\s*!=\s*0[uU]?\s*;\s*(\w+)\s*&=\s*(\w+)\s*-\s*1[uU]?\s*\)")
WORD_BITS = 32
_ENCLOSING_LINES = 10
_BISECTION = re.compile(r"while\s*\(\s*(\w+)\s*-\s*(\w+)\s*>\s*1\s*\)")  # how far up an enclosing loop's header may be
# The program evaluator's searches (fw_program.c): a line `DEFINE_SEARCH(name, type, key)` is
# the code of one search (gcc's line of a macro's code is the line that expands it), and the
# macro's body halves the n entries it searches, n -= n / 2, until one is left.
_SEARCH_EXPANSION = re.compile(r"^\s*DEFINE_SEARCH\(\s*(\w+)\s*,")
_HALVING_SEARCH = re.compile(r"#define DEFINE_SEARCH\(name, type, key\) static int name\(const type \*a, int n, "
                             r"ctrl_real x\) \{ int lo = 0; while \(n > 1\) \{ int half = n / 2; lo = [^;{}]+; "
                             r"n -= half; \} return lo; \}")


@dataclass
class LoopBound:
    count: int  # the most times its body runs
    source: str  # file:line, the bound's expression


_COPY = re.compile(r"\b(memcpy|memset|memmove)\s*\(")
# The arrays the controller copies hold reals (4 or 8 bytes, aligned to them): gcc's expanded
# copy loop moves at least one 4-byte word a turn.
WORD_BYTES = 4


def _arguments(text: str) -> list[str]:
    """The comma-separated arguments of a call, ``text`` starting after its parenthesis."""
    args, depth, cur = [], 0, ""
    for ch in text:
        if ch in ",)" and depth == 0:
            args.append(cur.strip())
            cur = ""
            if ch == ")":
                return args
            continue
        depth += (ch == "(") - (ch == ")")
        cur += ch
    return args


@dataclass(frozen=True)
class InputSection:
    start: int  # its address in the image
    size: int
    name: str  # e.g. .text.map_w (-ffunction-sections)
    object: Path  # the object file it came from, or the archive's member: lib.a(member.o)


def input_sections(map_file: Path) -> list[InputSection]:
    """The code sections of the object files and archive members (the C library) an image was
    linked from, by address, as the linker's map (``-Wl,-Map``) places them. Empty without a
    map."""
    if not map_file.is_file():
        return []
    text = map_file.read_text(encoding="utf-8", errors="replace")
    text = text[text.find("Linker script and memory map"):]  # not the discarded sections listed before it
    text = re.sub(r"^( \.\S+)\n\s+(?=0x)", r"\1 ", text, flags=re.M)  # a long name's address on its next line
    found = [InputSection(int(m.group(2), 16), int(m.group(3), 16), m.group(1), Path(m.group(4)))
             for m in re.finditer(r"^ (\.text\S*)\s+0x([0-9a-f]+)\s+0x([0-9a-f]+) (\S+\.o\)?)$", text, re.M)]
    return sorted((f for f in found if f.size > 0), key=lambda f: f.start)


class SourceLoops:
    """Loop counts read from the C source: the DWARF lines of an address (the inlining chain,
    innermost first), the first that is a `for` header, its bound evaluated by the build's
    preprocessor; a bound that is a parameter of an inlined function takes the argument at the
    call site, one frame out.

    With ``by_object`` (an Arm image, linked from address 0), an address is looked up in the
    object file it came from (the linker's map beside the image): in the image, the line table
    of a function ``--gc-sections`` dropped still describes addresses from 0 on (the relocation
    of a discarded section resolves to 0), and a large one (a robot's collision criterion,
    130 KB) covers the code linked there, the C library's too (which has no source lines:
    LIBRARY_LOOPS and down-counters count its loops). Not on RISC-V: its linker relaxes calls,
    so code moves from its object's offsets, and its image lies at 0x80000000, clear of those
    tables."""

    def __init__(self, addr2line: str, elf: Path, compiler: str, flags: list[str], by_object: bool = False):
        self.addr2line, self.elf, self.compiler, self.flags = addr2line, elf, compiler, list(flags)
        self._frames: dict[int, list[tuple[str, int]]] = {}
        self._files: dict[str, list[str]] = {}
        self._values: dict[tuple[str, str], int | None] = {}
        self._sections = input_sections(Path(elf).with_suffix(".map")) if by_object else []

    def _section_of(self, address: int) -> InputSection | None:
        for section in self._sections:  # few lookups a function: a scan is enough
            if section.start <= address < section.start + section.size:
                return section
        return None

    def locate(self, addresses: list[int]) -> None:
        todo = sorted({a for a in addresses if a not in self._frames})
        if not todo:
            return
        by_section: dict[InputSection | None, list[int]] = defaultdict(list)
        for a in todo:
            by_section[self._section_of(a)].append(a)
        for section, group in by_section.items():
            if section is not None and section.object.name.endswith(")"):  # the library's: no source read
                self._frames.update({a: [] for a in group})
            elif section is None or not section.object.is_file():
                self._read_frames([self.addr2line, "-a", "-i", "-e", str(self.elf), *(f"{a:#x}" for a in group)], 0)
            else:
                self._read_frames([self.addr2line, "-a", "-i", "-e", str(section.object), "-j", section.name,
                                   *(f"{a - section.start:#x}" for a in group)], section.start)

    def _read_frames(self, command: list[str], base: int) -> None:
        """addr2line's answer for each address (printed relative to ``base``)."""
        out = subprocess.run(command, capture_output=True, text=True, check=True).stdout.splitlines()
        current: list[tuple[str, int]] = []
        for line in out:
            if line.startswith("0x"):
                current = self._frames.setdefault(base + int(line, 16), [])
                continue
            path, _, number = line.rpartition(":")
            number = number.split()[0] if number.split() else ""
            current.append((path, int(number) if number.isdigit() else 0))

    def frames(self, address: int) -> list[tuple[str, int]]:
        """The (file, line) of a located address, innermost inlined function first."""
        return self._frames.get(address, [])

    def where(self, address: int) -> str:
        frames = self._frames.get(address) or [("??", 0)]
        return " < ".join(f"{Path(p).name}:{n}" for p, n in frames)

    def source(self, path: str) -> list[str]:
        if path not in self._files:
            self._files[path] = Path(path).read_text(encoding="utf-8").splitlines() if Path(path).is_file() else []
        return self._files[path]

    def bound(self, address: int) -> LoopBound | None:
        frames = self._frames.get(address, [])
        for depth, (path, line) in enumerate(frames):
            text = self.source(path)
            if not 0 < line <= len(text):
                continue
            copy = _COPY.search(text[line - 1])
            if copy and re.search(r"\b(for|while)\b", text[line - 1]):
                return None  # a copy and a loop on one line: which of them turns is unknown
            if copy:  # gcc's inline expansion of a fixed-size copy: a loop moving a word or more a turn
                size = self.evaluate(path, _arguments(text[line - 1][copy.end():])[2])
                if size is not None:
                    return LoopBound(-(-size // WORD_BYTES), f"{Path(path).name}:{line} ({copy.group(1)} of {size} B)")
            bits = _BITS.search(text[line - 1])
            if bits and bits.group(1) == bits.group(2) == bits.group(3) == bits.group(4):
                return LoopBound(WORD_BITS, f"{Path(path).name}:{line} (one turn per set bit of a 32-bit word)")
            m = _FOR.search(text[line - 1])
            if not m and line > 1 and text[line - 2].rstrip().endswith("{") and not re.search(
                    r"\b(for|while|do)\b", text[line - 1]):  # the first line of a loop's body
                m = _FOR.search(text[line - 2])
            if not m or not (m.group(1) == m.group(3) == (m.group(6) or m.group(7))):
                continue
            start = m.group(2)
            if not start.startswith("0") and not any(
                    (o := _FOR.search(up)) and o.group(1) == start and o.group(2).startswith("0")
                    for up in text[max(0, line - 1 - _ENCLOSING_LINES):line - 1]):
                continue
            expression = m.group(5)
            value = self.evaluate(path, expression)
            where = f"{Path(path).name}:{line} ({expression})"
            if value is None and depth + 1 < len(frames):  # a parameter of an inlined function
                argument = self.argument(path, line, expression, frames[depth + 1])
                if argument is not None:
                    value = self.evaluate(frames[depth + 1][0], argument)
                    where += f" = {argument} at {Path(frames[depth + 1][0]).name}:{frames[depth + 1][1]}"
            if value is None:
                return None
            return LoopBound(max(0, value + (1 if m.group(4) == "<=" else 0)), where)
        return None

    def argument(self, path: str, line: int, name: str, call: tuple[str, int]) -> str | None:
        """The argument the call at ``call`` passes for the parameter ``name`` of the function
        whose body holds ``path:line``."""
        text = self.source(path)
        for k in range(line - 1, -1, -1):
            d = re.search(r"\b(\w+)\s*\(([^()]*)\)\s*\{\s*$", text[k])
            if not d or d.group(1) in ("for", "if", "while", "switch"):
                continue
            params = [p.strip() for p in d.group(2).split(",")]
            index = next((i for i, p in enumerate(params) if re.search(rf"\b{name}$", p)), None)
            site = self.source(call[0])
            if index is None or not 0 < call[1] <= len(site):
                return None
            c = re.search(rf"\b{d.group(1)}\s*\(", site[call[1] - 1])
            args = _arguments(site[call[1] - 1][c.end():]) if c else []
            return args[index] if index < len(args) else None
        return None

    def evaluate(self, path: str, expression: str) -> int | None:
        """An integer constant expression as the build's preprocessor expands it in ``path``."""
        key = (path, expression)
        if key not in self._values:
            self._values[key] = self._preprocess(path, expression)
        return self._values[key]

    def _preprocess(self, path: str, expression: str) -> int | None:
        if not Path(path).is_file():
            return None
        probe = f'#include "{path}"\narmgen_bound_probe = ({expression});\n'
        done = subprocess.run([self.compiler, *self.flags, "-E", "-P", "-x", "c", "-"], input=probe,
                              capture_output=True, text=True)
        lines = [ln for ln in done.stdout.splitlines() if ln.startswith("armgen_bound_probe")]
        if done.returncode != 0 or not lines:
            return None
        text = lines[-1].split("=", 1)[1].rstrip("; ")
        text = re.sub(r"\((?:unsigned|int|long|size_t|u?int\d+_t)\)", "", text)
        text = re.sub(r"\b(\d+)[uUlL]+\b", r"\1", text)
        if re.fullmatch(r"[\d\s()+\-*/]+", text):
            return int(eval(text.replace("/", "//"), {"__builtins__": {}}))  # digits and operators only (checked above)
        return self._compile(path, expression)  # sizeof, enums: the compiler folds it

    def _compile(self, path: str, expression: str) -> int | None:
        probe = f'#include "{path}"\nconst long armgen_bound_probe = (long)({expression});\n'
        # (in a scratch folder: the build's -fstack-usage writes "-.su" beside an output to stdout)
        with tempfile.TemporaryDirectory(prefix="armgen-bound-") as scratch:
            done = subprocess.run([self.compiler, *self.flags, "-O0", "-w", "-S", "-o", "-", "-x", "c", "-"],
                                  input=probe, capture_output=True, text=True, cwd=scratch)
        m = re.search(r"^armgen_bound_probe:\s*\n\s*\.(?:word|4byte|long)\s+(-?\d+)", done.stdout, re.M)
        return int(m.group(1)) if done.returncode == 0 and m else None


@dataclass
class Bound:
    instructions: int
    loops: list[str]  # the loops counted: "function: source bound × N"


# C library routines whose loops run on their byte count (the third argument): Analyzer.sized.
SIZED_ROUTINES = ("memset", "memcpy", "memmove")


# The C library's loops that run on their data, with the stated count: the most turns a
# finite argument can take (docs/targets.md, "Static bound").
LIBRARY_LOOPS = {
    "__ieee754_sqrtf": (23, "newlib's sqrtf normalising a subnormal argument: one turn per leading zero of its "
                            "23-bit fraction"),
}


# newlib's sin/cos reduce an argument beyond 2^19 pi/2 (double; 2^7 pi/2 float: __ieee754_rem_pio2f's
# table path) with the Payne-Hanek routine, whose loops run on the exponent. Stated assumption:
# no argument of the controller's and the generated code's sin/cos is that large (joint angles
# within their limits, the time law's phases 2 pi s with s in [0, 1]), so those calls are not on
# any path the bound counts.
HUGE_ARGUMENT_REDUCTION = ("__kernel_rem_pio2", "__kernel_rem_pio2f")


class Analyzer:
    """Worst-case instruction bounds of an image's functions."""

    def __init__(self, elf: Path, family: str, tools_prefix: str, compiler: str, flags: list[str],
                 loop_caps: dict[str, int] | None = None,
                 block_cost: Callable[[list[Instruction]], int] = len):
        """family "arm" | "riscv"; tools_prefix e.g. "arm-none-eabi-"; compiler and flags: the
        build's (its preprocessor gives the loop bounds); loop_caps: a function name -> the
        most iterations its `*_LOOP_COUNT` loop runs (the caller's stop); block_cost: what one
        pass through a block's instructions costs (default: their number; CortexM4Cycles)."""
        self.elf = Path(elf)
        self.by_address = disassemble(tools_prefix + "objdump", self.elf)
        self.functions = {f.name: f for f in sorted(self.by_address.values(), key=lambda f: -f.start)}  # global names
        memory = Memory(tools_prefix + "objdump", self.elf) if family == "arm" else None
        self.isa = (lambda: ArmIsa(memory)) if family == "arm" else RiscvIsa
        self.family = family
        self.lines = SourceLoops(tools_prefix + "addr2line", self.elf, compiler, flags, by_object=family == "arm")
        self.loop_caps = dict(loop_caps or {})
        self.block_cost = block_cost
        self.search_ranges: dict[str, int] = {}  # function -> the most entries its bisection searches
        self.halving_ranges: dict[str, int] = {}  # fw_program.c's search -> the most entries it searches
        self._memo: dict[tuple[int, frozenset[str]], Bound] = {}
        self._unbounded = ""  # the lines of the last loop no source bound was found for

    def function_at(self, address: int) -> Function:
        fn = self.by_address.get(address & ~1)
        if fn is None:
            raise BoundError(f"a call to {address:#x}, which starts no function of {self.elf.name}")
        return fn

    def bound(self, name: str, avoid: tuple[str, ...] = ()) -> Bound:
        """The most instructions one call of the function ``name`` executes, its callees
        included; paths through a call of a function in ``avoid`` are not counted."""
        if name not in self.functions:
            raise BoundError(f"no function {name} in {self.elf.name}")
        return self._bound(self.functions[name], (*avoid, *HUGE_ARGUMENT_REDUCTION), ())

    def _bound(self, fn: Function, avoid: tuple[str, ...], stack: tuple[int, ...]) -> Bound:
        name = fn.name
        key = (fn.start, frozenset(avoid))
        if key in self._memo:
            return self._memo[key]
        if fn.start in stack:
            raise BoundError(f"recursion: {' -> '.join(self.by_address[a].name for a in (*stack, fn.start))}")
        blocks = blocks_of(fn, self.isa())
        loops: list[str] = []
        cost: dict[int, int] = {}
        for a, b in blocks.items():
            total: int | None = self.block_cost(b.instructions)
            for dest in b.calls:
                callee_fn = self.function_at(dest)
                callee = callee_fn.name
                if callee.split(".")[0] in avoid:  # gcc's clones (.constprop.0, .isra.0) of an avoided function
                    total = None
                    break
                if callee in SIZED_ROUTINES:
                    size = self._size_argument(b, dest, callee)
                    sub = self.sized(callee, size)
                    loops.append(f"{name}: {callee} of {size} B at {b.start:#x}: {sub}")
                    total += sub
                    continue
                callee_bound = self._bound(callee_fn, avoid, (*stack, fn.start))
                total += callee_bound.instructions
                loops += [s for s in callee_bound.loops if s not in loops]
            if total is not None:
                cost[a] = total
        result = self._longest(fn, blocks, cost, loops)
        if result is None:
            raise BoundError(f"{name}: no path returns (avoiding {', '.join(avoid) or 'nothing'})")
        bound = Bound(result, loops)
        self._memo[key] = bound
        return bound

    def sized(self, name: str, size: int) -> int:
        """A C library routine whose loops run on a byte count (memset, memcpy, memmove): the
        longest path with each loop left at once, plus ``size`` times the longest turn of any
        of its loops. Stated assumption (true of newlib's and picolibc's): every turn of every
        loop moves at least one byte, so all its loops together turn at most ``size`` times."""
        fn = self.functions.get(name)
        if fn is None:
            raise BoundError(f"no function {name} in {self.elf.name}")
        blocks = blocks_of(fn, self.isa())
        cost = {a: self.block_cost(b.instructions) for a, b in blocks.items()}
        for b in blocks.values():
            if b.calls:
                raise BoundError(f"{name} calls {', '.join(self.function_at(d).name for d in b.calls)}: not counted")
        turns: list[int] = []
        base = self._longest(fn, blocks, cost, [], turns)
        return base + size * max(turns, default=0)

    def _size_argument(self, block: Block, dest: int, callee: str) -> int:
        """The byte count a call passes in its third argument register, set by a constant move
        in the calling block."""
        reg = "r2" if self.family == "arm" else "a2"
        call = next(k for k, i in enumerate(block.instructions) if i.target == dest)
        for ins in reversed(block.instructions[:call]):
            ops = [o.strip() for o in ins.operands.split(",")]
            if ops and ops[0] == reg:
                m = re.fullmatch(r"#?(-?(?:0x[0-9a-f]+|\d+))", ops[-1]) if len(ops) == 2 else None
                if m and re.fullmatch(r"movs?(\.w)?|movw|li", ins.mnemonic):
                    return int(m.group(1), 0)
                break
        raise BoundError(f"the {callee} call at {block.instructions[call].address:#x}: its size is no constant")

    def _longest(self, fn: Function, blocks: dict[int, Block], cost: dict[int, int], loops: list[str],
                 turns: list[int] | None = None) -> int | None:
        """The longest entry-to-return path, loops collapsed innermost first. A block absent
        from ``cost`` is not on any path. With ``turns`` (a sized routine): each loop counts
        once out, its turn's length goes to ``turns``."""
        # Only the blocks on some counted path from the entry to a return (not through a
        # block that calls an avoided function): a loop elsewhere needs no bound.
        succ = {a: [s for s in b.successors if s in cost] for a, b in blocks.items() if a in cost}
        if fn.start not in succ:
            return None
        nodes = reachable(fn.start, succ)
        back_succ: dict[int, list[int]] = defaultdict(list)
        for a in nodes:
            for s in succ[a]:
                back_succ[s].append(a)
        returning = set()
        for e in (a for a in nodes if blocks[a].returns):
            returning |= reachable(e, back_succ) if e not in returning else set()
        nodes &= returning
        if fn.start not in nodes:
            return None
        succ = {a: [s for s in succ[a] if s in nodes] for a in nodes}
        dom = dominators(fn.start, succ)
        preds: dict[int, set[int]] = defaultdict(set)
        for a, ss in succ.items():
            for s in ss:
                preds[s].add(a)
        bodies: dict[int, set[int]] = defaultdict(set)
        latches: dict[int, set[int]] = defaultdict(set)
        for t in nodes:
            for h in succ[t]:
                if h in dom[t]:  # a back edge: its natural loop is what reaches t without passing h
                    body, todo = {h, t}, [t] if t != h else []
                    while todo:
                        for p in preds[todo.pop()]:
                            if p not in body:
                                body.add(p)
                                todo.append(p)
                    bodies[h] |= body
                    latches[h].add(t)
        # A retreating edge that is no back edge (irreducible flow) leaves a cycle in the
        # collapsed graph: _dag_longest raises.
        headers = sorted(bodies, key=lambda h: len(bodies[h]))  # inner loops first
        exits_of = {h: [a for a in bodies[h] if any(s not in bodies[h] for s in succ[a])] for h in headers}
        self.lines.locate([blocks[t].instructions[-1].address for h in headers for t in latches[h]]
                          + [blocks[a].instructions[-1].address for h in headers for a in exits_of[h]])
        weight: dict[int, int | None] = {a: cost.get(a) for a in nodes}
        graph = {a: set(ss) for a, ss in succ.items()}
        rep = {a: a for a in nodes}  # block -> the node standing for it (its outermost collapsed loop)
        for h in headers:
            body = {rep[a] for a in bodies[h]}
            body = self._collapse_irreducible(fn, blocks, graph, weight, rep, body, h, loops)
            inner = {a: {s for s in graph[a] if s in body} for a in body}
            once_round = _dag_longest(h, inner, weight, {rep[t] for t in latches[h]})
            out_path = _dag_longest(h, inner, weight, {a for a in body if graph[a] - body})
            if out_path is None:
                raise BoundError(f"{fn.name}: the loop at {h:#x} has no way out")
            if turns is not None:
                turns.append(once_round or 0)
                weight[h] = out_path
            else:
                # the branches of this loop's own blocks: one in an inner loop may be the inner
                # loop's test, whose count is not this loop's
                own = bodies[h] - set().union(*(bodies[g] for g in headers if g != h and bodies[g] < bodies[h]))
                lb = self._loop_bound(fn, h, [blocks[a].instructions[-1] for a in sorted(latches[h] & own)]
                                      + [blocks[a].instructions[-1] for a in exits_of[h] if a in own])
                if lb is None and fn.name in LIBRARY_LOOPS:
                    lb = LoopBound(*LIBRARY_LOOPS[fn.name])
                if lb is None and fn.name in self.search_ranges:
                    lb = self._search_bound(fn, blocks[h].instructions[-1], self.search_ranges[fn.name])
                if lb is None and self.halving_ranges:
                    lb = self._halving_bound([blocks[a].instructions[-1] for a in sorted(latches[h] | set(exits_of[h]))
                                              if a in own])
                if lb is None:
                    lb = self._counter_bound(fn, blocks, h, bodies[h], latches[h], preds)
                runs = lb.count + 1 if any(s not in bodies[h] for s in succ[h]) else max(lb.count, 1)
                weight[h] = out_path + (runs - 1) * (once_round or 0)
                loops.append(f"{fn.name}: loop at {h:#x}, {lb.source}: {lb.count}")
            outside = set().union(*(graph[a] for a in body)) - body
            for a in body - {h}:
                del graph[a], weight[a]
            graph[h] = outside
            for a in graph:
                if graph[a] & body:
                    graph[a] = (graph[a] - body) | {h}
            for a in bodies[h]:
                rep[a] = h
            for a, r in rep.items():
                if r in body:
                    rep[a] = h
        self._collapse_irreducible(fn, blocks, graph, weight, rep, set(graph), rep[fn.start], loops)
        ends = {rep[a] for a in nodes if blocks[a].returns}
        return _dag_longest(rep[fn.start], graph, weight, ends)

    def _collapse_irreducible(self, fn: Function, blocks: dict[int, Block], graph: dict[int, set[int]],
                              weight: dict[int, int | None], rep: dict[int, int], region: set[int], start: int,
                              loops: list[str]) -> set[int]:
        """Collapse each cycle of ``region`` (edges back to ``start`` aside) that is no natural
        loop (entered at more than one block: gcc's jump threading makes them) into one node:
        every node of it runs at most BOUND + 1 times, BOUND the loop's count from its source
        (as a natural loop's), so it costs (BOUND + 1) × the sum of its nodes. Returns the region
        with the collapsed nodes."""
        for scc in _cycles(region, {a: {s for s in graph[a] if s in region and s != start} for a in region}):
            stands_for = Counter(rep.values())  # a collapsed inner loop's branches test that loop: not these
            branches = [blocks[b].instructions[-1] for b in sorted(scc) if stands_for[b] == 1]
            self.lines.locate([i.address for i in branches])
            lb = self._loop_bound(fn, min(scc), branches)
            if lb is None:
                raise BoundError(f"{fn.name}: the loop through {', '.join(f'{a:#x}' for a in sorted(scc))} (several "
                                 f"entries) has no `for (i = 0; i < BOUND; ++i)` on its branches' lines "
                                 f"({self._unbounded})")
            if any(weight[a] is None for a in scc):
                scc = {a for a in scc if weight[a] is not None}  # a path through an avoided call is no path
            node = min(scc)
            total = (lb.count + 1) * sum(weight[a] for a in scc)
            loops.append(f"{fn.name}: loop at {node:#x} (entered at several blocks), {lb.source}: {lb.count}")
            outside = set().union(*(graph[a] for a in scc)) - scc
            for a in scc - {node}:
                del graph[a], weight[a]
            graph[node], weight[node] = outside, total
            for a in graph:
                if graph[a] & scc:
                    graph[a] = (graph[a] - scc) | {node}
            for b, r in rep.items():
                if r in scc:
                    rep[b] = node
            region = (region - scc) | {node}
        return region

    def _loop_bound(self, fn: Function, header: int, branches: list[Instruction]) -> LoopBound | None:
        """The loop's count from the `for` on the line of its back or exit branch."""
        found = [b for b in (self.lines.bound(i.address) for i in branches) if b is not None]
        if not found:
            self._unbounded = ", ".join(sorted({self.lines.where(i.address) for i in branches}))
            return None
        best = max(found, key=lambda b: b.count)
        cap = self.loop_caps.get(fn.name)
        if cap is not None and "_LOOP_COUNT" in best.source and cap < best.count:
            return LoopBound(cap, f"{best.source} capped at {cap} by the caller's stop")
        return best

    def _search_bound(self, fn: Function, branch: Instruction, size: int) -> LoopBound | None:
        """A bisection `while (hi - lo > 1)` whose first interval spans at most ``size``: each
        turn halves it, so it turns at most ceil(log2(size)) times."""
        self.lines.locate([branch.address])
        for path, line in self.lines.frames(branch.address):
            text = self.lines.source(path)
            if 0 < line <= len(text) and _BISECTION.search(text[line - 1]):
                return LoopBound(max(1, math.ceil(math.log2(size))), f"{Path(path).name}:{line} (bisection of at "
                                                                      f"most {size})")
        return None

    def _halving_bound(self, branches: list[Instruction]) -> LoopBound | None:
        """A search of fw_program.c (its branches on a `DEFINE_SEARCH(name, ...)` line, name in
        ``halving_ranges``) over at most N entries: each turn leaves ceil(n / 2) of n, so it
        turns at most ceil(log2(N)) times."""
        for branch in branches:
            frames = self.lines.frames(branch.address)
            if not frames:
                continue
            path, line = frames[0]
            text = self.lines.source(path)
            m = _SEARCH_EXPANSION.match(text[line - 1]) if 0 < line <= len(text) else None
            if m is None or m.group(1) not in self.halving_ranges:
                continue
            definition = " ".join(" ".join(text).replace("\\", " ").split())
            if not _HALVING_SEARCH.search(definition):
                raise BoundError(f"{Path(path).name}: DEFINE_SEARCH is not the halving search bound.py counts "
                                 "(while (n > 1) {{ int half = n / 2; ...; n -= half; }})")
            size = self.halving_ranges[m.group(1)]
            return LoopBound(math.ceil(math.log2(max(size, 1))),
                             f"{Path(path).name}:{line} ({m.group(1)} of at most {size} entries, halved each turn)")
        return None

    def _counter_bound(self, fn: Function, blocks: dict[int, Block], header: int, body: set[int], latches: set[int],
                       preds: dict[int, set[int]]) -> LoopBound:
        """A loop without source (a library's): a down-counter in the object code. The loop's
        only latch decrements a register by one and branches back while it is not zero
        (`subs rC, #1` [`cmp rC, #0`] `bne`; `addi rC, rC, -1` `bnez rC`); nothing else in the
        loop writes it; every way into the loop sets it to a constant (`movs rC, #N`, `li rC, N`)."""
        def fail() -> BoundError:
            return BoundError(f"{fn.name}: the loop at {header:#x} has no `for (i = 0; i < BOUND; ++i)` on its "
                              f"branches' lines ({self._unbounded}) and no down-counter: no iteration bound")
        if len(latches) != 1:
            raise fail()
        latch = blocks[next(iter(latches))].instructions
        branch = latch[-1]
        m = re.fullmatch(r"(\w+),\s*[0-9a-f]+.*", branch.operands) if branch.mnemonic == "bnez" else None
        counter = m.group(1) if m else None
        if branch.mnemonic.startswith("bne") and branch.mnemonic != "bnez":
            tail = [i for i in latch[-3:-1] if i.mnemonic not in ("cmp",) or re.fullmatch(r"\w+,\s*#0", i.operands)]
            dec = [i for i in tail if re.fullmatch(r"subs(\.w)?", i.mnemonic)
                   and re.fullmatch(r"(\w+),\s*(?:\1,\s*)?#1", i.operands)]
            counter = dec[-1].operands.split(",")[0] if dec else None
        elif counter is not None:
            if not any(i.mnemonic == "addi" and re.fullmatch(rf"{counter},\s*{counter},\s*-1", i.operands)
                       for i in latch[-3:-1]):
                counter = None
        if counter is None:
            raise fail()
        decrements = 0
        for a in body:
            for ins in blocks[a].instructions:
                if _writes(ins, counter):
                    decrements += 1
        if decrements != 1:
            raise fail()
        counts = []
        for entry in preds[header] - body:
            n = self._constant_into(blocks, preds, entry, counter)
            if n is None:
                raise fail()
            counts.append(n)
        if not counts:
            raise fail()
        return LoopBound(max(counts), f"{fn.name} at {header:#x}: counter {counter} from {max(counts)} down to 0")

    def _constant_into(self, blocks: dict[int, Block], preds: dict[int, set[int]], block: int, reg: str,
                       depth: int = 3) -> int | None:
        """The largest constant ``reg`` may hold at the end of ``block``: set in it, else in
        each of its predecessors (``depth`` blocks back at most); None if some path sets no
        constant."""
        for ins in reversed(blocks[block].instructions):
            if _writes(ins, reg):
                m = re.fullmatch(rf"{reg},\s*#?(\d+)", ins.operands)
                ok = re.fullmatch(r"movs?(\.w)?|movw|li", ins.mnemonic)
                return int(m.group(1)) if m and ok else None
        if depth == 0 or not preds[block]:
            return None
        values = [self._constant_into(blocks, preds, p, reg, depth - 1) for p in preds[block]]
        return None if None in values else max(values)


_NO_DESTINATION = ("cmp", "cmn", "tst", "teq", "str", "vstr", "push", "vpush", "it", "vcmp", "b", "cb",
                   "sw", "sh", "sb", "fsw", "fsd", "j", "nop")


def _writes(ins: Instruction, reg: str) -> bool:
    """Whether the instruction writes the core register ``reg`` (its first operand, or a
    register list of pop/ldm)."""
    if ins.mnemonic.startswith(("pop", "ldm")):
        return bool(re.search(rf"[{{,\s]{reg}[,}}]", ins.operands))
    if ins.mnemonic.startswith(_NO_DESTINATION) and not ins.mnemonic.startswith(("bic", "bfi", "bfc")):
        return False
    return ins.operands.split(",")[0].strip().rstrip("!") == reg


def _cycles(nodes: set[int], graph: dict[int, set[int]]) -> list[set[int]]:
    """The strongly connected components of ``graph`` that hold a cycle (Tarjan's, iterative)."""
    index: dict[int, int] = {}
    low: dict[int, int] = {}
    stack: list[int] = []
    on: set[int] = set()
    out: list[set[int]] = []
    counter = 0
    for root in sorted(nodes):
        if root in index:
            continue
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            node, it = work[-1]
            advanced = False
            for s in it:
                if s not in index:
                    index[s] = low[s] = counter
                    counter += 1
                    stack.append(s)
                    on.add(s)
                    work.append((s, iter(sorted(graph.get(s, ())))))
                    advanced = True
                    break
                if s in on:
                    low[node] = min(low[node], index[s])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                comp = set()
                while True:
                    x = stack.pop()
                    on.discard(x)
                    comp.add(x)
                    if x == node:
                        break
                if len(comp) > 1 or node in graph.get(node, ()):
                    out.append(comp)
    return out


def _dag_longest(start: int, graph: dict[int, set[int]], weight: dict[int, int | None], ends: set[int]) -> int | None:
    """The heaviest path from ``start`` to a node of ``ends`` (both counted) in the graph
    without its edges back to ``start``; None when no end is reachable through counted nodes.
    The graph must be acyclic otherwise."""
    order: list[int] = []  # post-order of the nodes reachable from start
    state = {start: 1}
    stack = [(start, iter(graph.get(start, ())))]
    while stack:
        node, it = stack[-1]
        for s in it:
            if s == start:
                continue
            if state.get(s) == 1:
                raise BoundError(f"a cycle through {s:#x} that is no natural loop (irreducible control flow)")
            if s not in state:
                state[s] = 1
                stack.append((s, iter(graph.get(s, ()))))
                break
        else:
            state[node] = 2
            order.append(node)
            stack.pop()
    best: dict[int, int | None] = {}
    for n in order:  # successors first
        w = weight.get(n)
        if w is None:
            best[n] = None
            continue
        tails = [best[s] for s in graph.get(n, ()) if s != start and best.get(s) is not None]
        own = [w] if n in ends else []
        best[n] = max(own + [w + t for t in tails]) if own or tails else None
    return best[start]


# The controller's tick of each mode (controller.c): ctrl_tick calls one of them (or has it
# inlined: then the other modes' paths stay in the bound, which is still a bound).
MODE_TICK = {"RESOLVED_RATE": "tick_resolved_rate", "PLAYBACK": "tick_playback",
             "FAULT_TOLERANT": "tick_fault_tolerant", "WEIGHTED_GPM": "tick_weighted_gpm"}
# What a tick of a task running in one mode never calls: the MOVE_TO command's planner and its
# IK (a MOVE_TO or MOVE_TO_JOINTS command's first tick; not a mode's running tick), the
# program evaluator (a task whose path is a program), the PTP evaluator (PLAYBACK's).
MOVE_TO_PLANNER = ("plan_move_to",)
PROGRAM_EVALUATOR = ("fw_program_desired",)
PTP_EVALUATOR = ("fw_ptp_eval",)


def tick_avoid(prefix: str, mode: str, program: bool = False) -> tuple[str, ...]:
    """The functions a running tick of ``mode`` does not reach (Analyzer.bound's avoid)."""
    if mode not in MODE_TICK:
        raise BoundError(f"no tick bound for mode {mode}: one of {', '.join(MODE_TICK)}")
    avoid = [t for m, t in MODE_TICK.items() if m != mode] + list(MOVE_TO_PLANNER) + [f"{prefix}_ik"]
    if not program:
        avoid += PROGRAM_EVALUATOR
    if mode != "PLAYBACK":
        avoid += PTP_EVALUATOR
    return tuple(avoid)


def generated_functions(analyzer: Analyzer, prefix: str, header: Path) -> list[str]:
    """The functions the generated header ``header`` declares that are in the image."""
    text = Path(header).read_text(encoding="utf-8")
    names = re.findall(rf"^(?!static)\w[\w ]*?\b({prefix}_\w+)\(", text, re.M)
    return [n for n in dict.fromkeys(names) if n in analyzer.functions]


def analyzer(target: Target, elf: Path, flags: list[str], prefix: str | None = None,
             ik_iterations: int | None = None, block_cost: Callable[[list[Instruction]], int] = len) -> Analyzer:
    """The Analyzer of an image built for ``target`` with the compile ``flags``; with
    ``prefix`` and ``ik_iterations``, the generated IK's step loop (``<prefix>_ik_step_*_loop``,
    which stops after max_iterations steps: armgen.symbolic.ik) counted for that many steps."""
    tools = target.compiler.removesuffix("gcc")
    a = Analyzer(elf, target.family, tools, target.compiler, flags, block_cost=block_cost)
    if prefix is not None and ik_iterations is not None:
        a.loop_caps.update({name: ik_iterations for name in a.functions
                            if name.startswith(f"{prefix}_ik_step_") and name.endswith("_loop")})
    return a


# fw_program.c's searches, each with the size macro of the table it searches (program_table.h)
# and what it searches less: search_map searches a curve's rows - 1 intervals, and a curve has
# at most the table's rows (fw_program_check).
PROGRAM_SEARCHES = {"search_segment": ("FW_PROGRAM_SEGMENTS", 0), "search_piece": ("FW_PROGRAM_PIECES", 0),
                    "search_map": ("FW_PROGRAM_MAPS", -1), "search_knot": ("FW_PROGRAM_KNOTS", 0)}


def program_search_ranges(header: str) -> dict[str, int]:
    """The most entries each search of fw_program.c searches in a tick of the task whose
    task_params.h is ``header``: the sizes of its program table. Stated assumption: the
    controller's program is that table (path_program.h's `.program`, nothing replaces it)."""
    sizes = dict(re.findall(r"^#define (FW_PROGRAM_[A-Z]+) (\d+)\s*$", header, re.M))
    missing = [macro for macro, _ in PROGRAM_SEARCHES.values() if macro not in sizes]
    if missing:
        raise BoundError(f"the task's program table defines no {', '.join(missing)} (program_table.h's size macros)")
    return {search: int(sizes[macro]) + less for search, (macro, less) in PROGRAM_SEARCHES.items()}


def set_tick_ranges(a: Analyzer, mode: str, header: str) -> None:
    """The ranges of the searches a running tick of ``mode`` makes, in ``a``: PLAYBACK's PTP
    evaluator bisects at most CTRL_MAX_SEGMENTS segments (ctrl_init refuses a plan of more than
    the build holds); a program task's evaluator searches its table (``header``: task_params.h)."""
    if mode.upper() == "PLAYBACK":
        segments = a.lines.evaluate(str(FIRMWARE_DIR / "controller.h"), "CTRL_MAX_SEGMENTS")
        if segments is None:
            raise BoundError("CTRL_MAX_SEGMENTS: not a constant under the build's flags")
        a.search_ranges.update({name: segments for name in PTP_EVALUATOR})
    if "CTRL_PATH_PROGRAM" in header:
        a.halving_ranges.update(program_search_ranges(header))


def tick_bound(target: Target, elf: Path, flags: list[str], prefix: str, mode: str, header: str) -> Bound:
    """The static bound of one ``ctrl_tick`` of a firmware image running a task of ``mode``
    (FirmwareTask.mode, e.g. "weighted_gpm"; ``header`` its task_params.h): built with the
    compile ``flags`` (FirmwareBuilder.cflags)."""
    a = analyzer(target, elf, flags)
    set_tick_ranges(a, mode, header)
    return a.bound("ctrl_tick", tick_avoid(prefix, mode.upper(), "CTRL_PATH_PROGRAM" in header))


@dataclass(frozen=True)
class CortexM4Cycles:
    """Processor cycles of a block on a Cortex-M4F running from flash with ``wait_states``
    (e.g. STM32F4 at 168 MHz: 5), an upper bound under these stated assumptions:

    - each instruction its worst timing of the Cortex-M4 Technical Reference Manual (r0p1,
      3.3.1) and of the FPU's (FPv4-SP, 7.2.2): every branch taken with the longest pipeline
      refill (1 + 3), every load 2 cycles (none pipelined with its neighbour), LDM/STM/PUSH/POP
      1 + one per register (and the refill when it loads pc), division 12 (integer) or 14
      (VDIV, VSQRT), multiply-accumulate 2 (integer) or 3 (VMLA, VFMA ...);
    - the flash delivers 16-byte lines, each costing ``wait_states`` cycles, and nothing is
      cached or prefetched (an ART accelerator or cache only removes cycles): a block fetches
      at most its size / 16 + 1 lines, and every load may read the flash (constants, the
      literal pools), ``wait_states`` more;
    - no interrupt, no bus contention (DMA), zero-wait-state SRAM for the data.
    """

    wait_states: int = 5
    line_bytes: int = 16

    def __call__(self, instructions: list[Instruction]) -> int:
        size = sum(i.size for i in instructions)
        fetch = self.wait_states * (-(-size // self.line_bytes) + 1)
        return fetch + sum(self.instruction(i) for i in instructions)

    def instruction(self, ins: Instruction) -> int:
        # the mnemonic as printed, and without a condition suffix (an IT block's popeq, ldrne)
        names = (ins.mnemonic, re.sub(rf"({_ARM_COND})(?=(\.\w+)?$)", "", ins.mnemonic))

        def kind(*prefixes: str) -> bool:
            return any(n.startswith(prefixes) for n in names)

        refill = 3
        if kind("pop", "push", "ldm", "stm", "vpush", "vpop", "vldm", "vstm"):
            span = re.search(r"\{([^}]*)\}", ins.operands)
            words = 1  # a register list of one word at least
            if span:  # {r4, r5, lr}, {d8-d15}: one cycle per 32-bit word moved
                words = 0
                for item in span.group(1).split(","):
                    ends = [int(x) for x in re.findall(r"\d+", item)]
                    width = 2 if item.strip().startswith("d") else 1
                    words += width * (ends[-1] - ends[0] + 1 if len(ends) == 2 else 1)
            loads = kind("pop", "ldm", "vpop", "vldm")
            return 1 + words + (refill if re.search(r"\bpc\b", ins.operands) else 0) + self.wait_states * loads
        if _ARM_B.match(ins.mnemonic) or kind("bl", "bx", "cbz", "cbnz"):
            return 1 + refill
        if kind("tbb", "tbh"):
            return 1 + refill + 2 + self.wait_states  # the table's load from flash
        if kind("ldr", "vldr"):
            double = re.match(r"d\d", ins.operands) is not None or kind("ldrd")
            return (3 if double else 2) + self.wait_states + (refill if ins.operands.startswith("pc") else 0)
        if kind("str", "vstr"):
            return 3 if kind("strd") or re.match(r"d\d", ins.operands) else 2
        if kind("sdiv", "udiv"):
            return 12
        if kind("vdiv", "vsqrt"):
            return 14
        if kind("vmla", "vmls", "vnmla", "vnmls", "vfma", "vfms", "vfnma", "vfnms"):
            return 3
        if kind("mla", "mls", "smla", "umla", "smlal", "umlal"):
            return 2
        return 1


@dataclass(frozen=True)
class CortexM0PlusCycles:
    """Processor cycles of a block on a Cortex-M0+ running from zero-wait-state memory (the
    RP2040's SRAM: a copy_to_ram build; its XIP flash cache is not modelled), an upper bound
    under these stated assumptions:

    - each instruction its worst timing of the Cortex-M0+ Technical Reference Manual (3.3):
      every branch taken (B, Bcc 2, BL 3, BX/BLX 2), every load and store 2, LDM/STM/PUSH/POP
      1 + one per register, POP with pc 3 + one per register, MULS 1 (the single-cycle
      multiplier of the RP2040 and the SAMD21), MRS/MSR/barriers 4;
    - no interrupt, no bus contention (DMA, the other core).
    """

    def __call__(self, instructions: list[Instruction]) -> int:
        return sum(self.instruction(i) for i in instructions)

    @staticmethod
    def instruction(ins: Instruction) -> int:
        mn = ins.mnemonic
        if mn.startswith(("pop", "push", "ldm", "stm")):
            words = len(re.findall(r"\b(?:r\d+|lr|pc)\b", ins.operands.split("{", 1)[-1]))
            return (3 if re.search(r"\bpc\b", ins.operands) else 1) + words
        if mn == "bl":
            return 3
        if _ARM_B.match(mn) or mn in ("bx", "blx"):
            return 2
        if mn.startswith(("ldr", "str")):
            return 2
        if mn in ("mrs", "msr", "dmb", "dsb", "isb"):
            return 4
        if mn == "mov" and ins.operands.startswith("pc"):
            return 2  # a jump table's branch
        return 1
