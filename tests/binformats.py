"""Just enough of PE, Mach-O and ELF to check a Python extension module built for another system.

Pure Python (no objdump, no llvm tools): each reader returns a :class:`NativeLib` with the CPU,
the exported symbols, the libraries it loads and what the loader on its system checks (glibc
versions, the macOS version, an arm64 code signature).
"""

from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass, field


@dataclass
class NativeLib:
    format: str  # "PE32+", "Mach-O", "ELF64"
    machine: str  # "x86_64" or "arm64"
    shared_library: bool
    exports: set[str]
    needed: list[str]  # DLL names (PE), dylib paths (Mach-O), DT_NEEDED (ELF)
    glibc_needed: tuple[int, int] | None = None  # ELF: the newest GLIBC_x.y a symbol needs
    macos_min: tuple[int, int] | None = None  # Mach-O: LC_BUILD_VERSION / LC_VERSION_MIN_MACOSX
    code_signature: str | None = None  # Mach-O: None, or "valid ..." with what was checked
    notes: list[str] = field(default_factory=list)


def read(data: bytes) -> NativeLib:
    if data[:2] == b"MZ":
        return read_pe(data)
    if data[:4] == b"\xcf\xfa\xed\xfe":
        return read_macho(data)
    if data[:4] == b"\x7fELF":
        return read_elf(data)
    raise ValueError(f"not PE, 64-bit Mach-O or ELF: starts with {data[:4]!r}")


def _cstr(data: bytes, off: int) -> str:
    return data[off : data.index(b"\0", off)].decode()


# --- PE (Windows DLL / .pyd) -------------------------------------------------------------------

_PE_MACHINES = {0x8664: "x86_64", 0xAA64: "arm64", 0x14C: "x86"}


def read_pe(data: bytes) -> NativeLib:
    pe = struct.unpack_from("<I", data, 0x3C)[0]
    if data[pe : pe + 4] != b"PE\0\0":
        raise ValueError("no PE signature")
    machine, nsect, _, _, _, opt_size, characteristics = struct.unpack_from(
        "<HHIIIHH", data, pe + 4
    )
    opt = pe + 24
    magic = struct.unpack_from("<H", data, opt)[0]
    if magic != 0x20B:
        raise ValueError(f"optional header magic {magic:#x}, not PE32+")
    n_dirs = struct.unpack_from("<I", data, opt + 108)[0]
    dirs = [struct.unpack_from("<II", data, opt + 112 + 8 * i) for i in range(n_dirs)]
    sections = []
    for i in range(nsect):
        s = opt + opt_size + 40 * i
        vsize, vaddr, raw_size, raw_ptr = struct.unpack_from("<IIII", data, s + 8)
        sections.append((vaddr, max(vsize, raw_size), raw_ptr))

    def off(rva: int) -> int:
        for vaddr, size, raw in sections:
            if vaddr <= rva < vaddr + size:
                return rva - vaddr + raw
        raise ValueError(f"RVA {rva:#x} is in no section")

    exports: set[str] = set()
    exp_rva, exp_size = dirs[0]
    if exp_size:
        e = off(exp_rva)
        n_names, _, names_rva = struct.unpack_from("<III", data, e + 24)
        for i in range(n_names):
            exports.add(_cstr(data, off(struct.unpack_from("<I", data, off(names_rva) + 4 * i)[0])))
    needed = []
    imp_rva, imp_size = dirs[1]
    if imp_size:
        d = off(imp_rva)
        while True:
            desc = struct.unpack_from("<IIIII", data, d)
            if not any(desc):
                break
            needed.append(_cstr(data, off(desc[3])))
            d += 20
    return NativeLib(
        format="PE32+",
        machine=_PE_MACHINES.get(machine, hex(machine)),
        shared_library=bool(characteristics & 0x2000),  # IMAGE_FILE_DLL
        exports=exports,
        needed=needed,
    )


# --- Mach-O (macOS .so / .dylib) ---------------------------------------------------------------

_MACHO_CPUS = {0x01000007: "x86_64", 0x0100000C: "arm64"}
LC_CODE_SIGNATURE, LC_VERSION_MIN_MACOSX, LC_BUILD_VERSION = 0x1D, 0x24, 0x32
LC_DYLD_INFO, LC_DYLD_INFO_ONLY, LC_DYLD_EXPORTS_TRIE = 0x22, 0x80000022, 0x80000033
LC_LOAD_DYLIBS = {0xC, 0x80000018, 0x8000001F, 0x80000023}  # load, weak, reexport, upward


def _uleb(data: bytes, i: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        b = data[i]
        i += 1
        value |= (b & 0x7F) << shift
        shift += 7
        if b < 0x80:
            return value, i


def _export_trie(trie: bytes) -> set[str]:
    names: set[str] = set()
    stack = [(0, "")]
    seen = set()
    while stack:
        node, prefix = stack.pop()
        if node in seen:  # a malformed trie must not loop
            raise ValueError("export trie has a cycle")
        seen.add(node)
        terminal, i = _uleb(trie, node)
        if terminal:
            names.add(prefix)
        i += terminal
        n_children = trie[i]
        i += 1
        for _ in range(n_children):
            end = trie.index(b"\0", i)
            edge = trie[i:end].decode()
            child, i = _uleb(trie, end + 1)
            stack.append((child, prefix + edge))
    return names


def _version(v: int) -> tuple[int, int]:
    return v >> 16, (v >> 8) & 0xFF


def _check_code_signature(data: bytes, dataoff: int, datasize: int) -> str:
    """Verifies an (ad-hoc) code signature's page hashes: what arm64 macOS checks at load."""
    blob = data[dataoff : dataoff + datasize]
    magic, _, count = struct.unpack_from(">III", blob, 0)
    if magic != 0xFADE0CC0:
        raise ValueError(f"code signature superblob magic {magic:#x}")
    for k in range(count):
        slot, cd_off = struct.unpack_from(">II", blob, 12 + 8 * k)
        if slot != 0:  # CSSLOT_CODEDIRECTORY
            continue
        (cd_magic, _, _, flags, hash_off, ident_off, _, n_code, code_limit) = struct.unpack_from(
            ">IIIIIIIII", blob, cd_off
        )
        hash_size, hash_type, _, page_log2 = struct.unpack_from(">BBBB", blob, cd_off + 36)
        if cd_magic != 0xFADE0C02:
            raise ValueError(f"code directory magic {cd_magic:#x}")
        if code_limit != dataoff:
            raise ValueError(f"signature covers {code_limit} bytes, the code ends at {dataoff}")
        algo = {1: hashlib.sha1, 2: hashlib.sha256}[hash_type]
        page = 1 << page_log2
        for i in range(n_code):
            want = blob[cd_off + hash_off + i * hash_size : cd_off + hash_off + (i + 1) * hash_size]
            got = algo(data[i * page : min((i + 1) * page, code_limit)]).digest()[:hash_size]
            if want != got:
                raise ValueError(f"code signature: page {i} hash differs")
        kind = "ad-hoc" if flags & 0x2 else "signed"
        ident = _cstr(blob, cd_off + ident_off)
        return f"valid {kind} ({ident}, {n_code} pages, {algo().name})"
    raise ValueError("code signature has no code directory")


def read_macho(data: bytes) -> NativeLib:
    cputype, _, filetype, ncmds, _, _ = struct.unpack_from("<iIIIII", data, 4)
    exports: set[str] = set()
    needed: list[str] = []
    macos_min = None
    signature = None
    lc = 32
    for _ in range(ncmds):
        cmd, size = struct.unpack_from("<II", data, lc)
        if cmd in (LC_DYLD_INFO, LC_DYLD_INFO_ONLY):
            export_off, export_size = struct.unpack_from("<II", data, lc + 40)
            if export_size:
                exports |= _export_trie(data[export_off : export_off + export_size])
        elif cmd == LC_DYLD_EXPORTS_TRIE:
            trie_off, trie_size = struct.unpack_from("<II", data, lc + 8)
            exports |= _export_trie(data[trie_off : trie_off + trie_size])
        elif cmd in LC_LOAD_DYLIBS:
            needed.append(_cstr(data, lc + struct.unpack_from("<I", data, lc + 8)[0]))
        elif cmd == LC_BUILD_VERSION:
            macos_min = _version(struct.unpack_from("<I", data, lc + 12)[0])
        elif cmd == LC_VERSION_MIN_MACOSX:
            macos_min = _version(struct.unpack_from("<I", data, lc + 8)[0])
        elif cmd == LC_CODE_SIGNATURE:
            signature = _check_code_signature(data, *struct.unpack_from("<II", data, lc + 8))
        lc += size
    return NativeLib(
        format="Mach-O",
        machine=_MACHO_CPUS.get(cputype, hex(cputype)),
        shared_library=filetype in (6, 8),  # MH_DYLIB, MH_BUNDLE
        exports=exports,
        needed=needed,
        macos_min=macos_min,
        code_signature=signature,
    )


# --- ELF (Linux .so) ---------------------------------------------------------------------------

_ELF_MACHINES = {62: "x86_64", 183: "arm64"}
SHT_DYNAMIC, SHT_DYNSYM, SHT_GNU_VERNEED = 6, 11, 0x6FFFFFFE


def read_elf(data: bytes) -> NativeLib:
    if data[4] != 2 or data[5] != 1:
        raise ValueError("not a little-endian 64-bit ELF")
    e_type, e_machine = struct.unpack_from("<HH", data, 16)
    shoff = struct.unpack_from("<Q", data, 0x28)[0]
    shentsize, shnum = struct.unpack_from("<HH", data, 0x3A)
    sections = [
        struct.unpack_from("<IIQQQQIIQQ", data, shoff + i * shentsize) for i in range(shnum)
    ]

    def strtab(index: int) -> int:
        return sections[index][4]  # sh_offset

    exports: set[str] = set()
    needed: list[str] = []
    glibc: tuple[int, int] | None = None
    for _, sh_type, _, _, offset, size, link, info, _, entsize in sections:
        if sh_type == SHT_DYNSYM:
            for k in range(size // entsize):
                name, st_info, _, shndx = struct.unpack_from("<IBBH", data, offset + k * entsize)
                if shndx != 0 and st_info >> 4 in (1, 2) and st_info & 0xF == 2:  # GLOBAL/WEAK FUNC
                    exports.add(_cstr(data, strtab(link) + name))
        elif sh_type == SHT_DYNAMIC:
            for k in range(size // 16):
                tag, val = struct.unpack_from("<qQ", data, offset + 16 * k)
                if tag == 1:  # DT_NEEDED
                    needed.append(_cstr(data, strtab(link) + val))
        elif sh_type == SHT_GNU_VERNEED:
            vn = offset
            for _ in range(info):
                _, cnt, _, aux, nxt = struct.unpack_from("<HHIII", data, vn)
                a = vn + aux
                for _ in range(cnt):
                    _, _, _, vna_name, vna_next = struct.unpack_from("<IHHII", data, a)
                    ver = _cstr(data, strtab(link) + vna_name)
                    if ver.startswith("GLIBC_2."):
                        v = tuple(int(x) for x in ver[len("GLIBC_") :].split(".")[:2])
                        glibc = max(glibc or v, v)  # type: ignore[assignment]
                    a += vna_next
                vn += nxt
    return NativeLib(
        format="ELF64",
        machine=_ELF_MACHINES.get(e_machine, str(e_machine)),
        shared_library=e_type == 3,  # ET_DYN
        exports=exports,
        needed=needed,
        glibc_needed=glibc,
    )
