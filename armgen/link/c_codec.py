"""The C side of :mod:`.protocol`'s table: ``fw_link_msgs.{h,c}`` of the firmware stub, from the
templates ``armgen/data/templates/firmware/link_msgs.{h,c}``.

The generated pair is robot-independent (arrays of ``CTRL_NDOF``) and checked in beside the
stub's other sources (``armgen/data/firmware_stub/``); tests/test_link_codec.py regenerates and
diffs it. ``python -m armgen.link.c_codec`` rewrites it after a change of the table.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from string import Template

from .protocol import CRITERIA, FLAGS, MESSAGES, NDOF, REPLIES, RESULTS, VERSION, C_TYPES, Field, Message

STUB_FILES = ("fw_link_msgs.h", "fw_link_msgs.c")


def _c_count(f: Field) -> str:
    return "CTRL_NDOF" if f.count == NDOF else str(f.count)


def _size_expr(m: Message) -> str:
    width = {"u8": 1, "u16": 2, "u32": 4, "f32": 4}
    terms = [f"{width[f.kind]}u * (size_t)({_c_count(f)})" if f.is_array else f"{width[f.kind]}u" for f in m.fields]
    return "(" + " + ".join(terms) + ")" if terms else "0u"


def _lower(m: Message) -> str:
    return m.name.lower()


def _struct(m: Message) -> str:
    lines = [f"/* {m.name} ({m.sender} -> {'board' if m.sender == 'host' else 'host'}): {m.doc} */", "typedef struct {"]
    for f in m.fields:
        dim = f"[{_c_count(f)}]" if f.is_array else ""
        lines.append(f"  {C_TYPES[f.kind]} {f.name}{dim}; /* {f.doc} */")
    lines.append(f"}} fw_link_{_lower(m)};")
    return "\n".join(lines) + "\n"


def _functions(m: Message) -> str:
    low = _lower(m)
    if not m.fields:
        return (f"\nint fw_link_unpack_{low}(const uint8_t *body, size_t len) {{\n"
                f"  (void)body;\n  return len == FW_LINK_{m.name}_SIZE;\n}}\n")
    pack, unpack = [], []
    for f in m.fields:
        if f.is_array:
            pack.append(f"  for (i = 0; i < (size_t)({_c_count(f)}); ++i) {{\n    put_{f.kind}(&p, m->{f.name}[i]);\n  }}")
            unpack.append(f"  for (i = 0; i < (size_t)({_c_count(f)}); ++i) {{\n    m->{f.name}[i] = get_{f.kind}(&p);\n  }}")
        else:
            pack.append(f"  put_{f.kind}(&p, m->{f.name});")
            unpack.append(f"  m->{f.name} = get_{f.kind}(&p);")
    has_array = any(f.is_array for f in m.fields)
    decl = "  size_t i;\n" if has_array else ""
    return (f"\nsize_t fw_link_pack_{low}(const fw_link_{low} *m, uint8_t *out) {{\n{decl}  uint8_t *p = out;\n"
            + "\n".join(pack) + f"\n  return (size_t)(p - out);\n}}\n"
            f"\nint fw_link_unpack_{low}(const uint8_t *body, size_t len, fw_link_{low} *m) {{\n{decl}"
            f"  const uint8_t *p = body;\n  if (len != FW_LINK_{m.name}_SIZE) {{\n    return 0;\n  }}\n"
            + "\n".join(unpack) + "\n  return 1;\n}\n")


def _prototypes(m: Message) -> str:
    low = _lower(m)
    if not m.fields:
        return f"int fw_link_unpack_{low}(const uint8_t *body, size_t len); /* 1: an empty body */\n"
    return (f"size_t fw_link_pack_{low}(const fw_link_{low} *m, uint8_t *out);\n"
            f"int fw_link_unpack_{low}(const uint8_t *body, size_t len, fw_link_{low} *m);\n")


def _largest(messages: list[Message]) -> Message:
    """The message with the largest body for any joint count (sizes are linear in ndof: the
    largest at 1 and at 255 joints, the most a HELLO_REPLY can name, is the largest between)."""
    small = max(messages, key=lambda m: m.body_size(1))
    large = max(messages, key=lambda m: m.body_size(255))
    if small is not large:
        raise ValueError(f"no message is the largest for every joint count ({small.name} at 1, {large.name} at 255)")
    return small


def render() -> dict[str, str]:
    """The two files' text."""
    templates = resources.files("armgen.data").joinpath("templates/firmware")
    with_body = [m for m in MESSAGES if m.fields]
    sizes = "".join(f"#define FW_LINK_{m.name}_SIZE {_size_expr(m)}\n" for m in MESSAGES)
    largest = _largest(with_body)
    sizes += f"/* the largest body (for every joint count: armgen.link.c_codec checks it) */\n" \
             f"#define FW_LINK_MAX_BODY FW_LINK_{largest.name}_SIZE\n"
    values = {
        "version": str(VERSION),
        "codes": "".join(f"#define FW_LINK_{m.name} 0x{m.code:02X}u /* {m.doc} */\n" for m in MESSAGES),
        "sizes": sizes,
        "results": "".join(f"#define FW_LINK_RESULT_{n} {i}u /* {d} */\n" for i, (n, d) in enumerate(RESULTS)),
        "flags": "".join(f"#define FW_LINK_FLAG_{n} {1 << i}u /* {d} */\n" for i, (n, d) in enumerate(FLAGS)),
        "replies": "".join(f"#define FW_LINK_REPLY_{n} {i}u /* {d} */\n" for i, (n, d) in enumerate(REPLIES)),
        "criteria": "".join(f"#define FW_LINK_CRITERION_{n} {i}u /* {d} */\n" for i, (n, d) in enumerate(CRITERIA)),
        "structs": "\n" + "\n".join(_struct(m) for m in with_body),
        "union_members": "\n".join(f"  fw_link_{_lower(m)} {_lower(m)};" for m in with_body),
        "prototypes": "".join(_prototypes(m) for m in MESSAGES),
    }
    header = Template(templates.joinpath("link_msgs.h").read_text(encoding="utf-8")).substitute(values)
    unpack_cases = "\n".join(
        f"    case FW_LINK_{m.name}: return fw_link_unpack_{_lower(m)}(body, len, &m->{_lower(m)});" if m.fields else
        f"    case FW_LINK_{m.name}: return fw_link_unpack_{_lower(m)}(body, len);" for m in MESSAGES)
    pack_cases = "\n".join(
        f"    case FW_LINK_{m.name}: return fw_link_pack_{_lower(m)}(&m->{_lower(m)}, out);" if m.fields else
        f"    case FW_LINK_{m.name}: return FW_LINK_{m.name}_SIZE;" for m in MESSAGES)
    source = Template(templates.joinpath("link_msgs.c").read_text(encoding="utf-8")).substitute(
        version=str(VERSION), functions="".join(_functions(m) for m in MESSAGES),
        unpack_cases=unpack_cases, pack_cases=pack_cases)
    return {"fw_link_msgs.h": header, "fw_link_msgs.c": source}


def stub_dir() -> Path:
    return Path(str(resources.files("armgen.data").joinpath("firmware_stub")))


def write(folder: Path | None = None) -> list[Path]:
    folder = folder or stub_dir()
    paths = []
    for name, text in render().items():
        path = folder / name
        path.write_text(text, encoding="utf-8")
        paths.append(path)
    return paths


if __name__ == "__main__":
    for written in write():
        print(written)
