#!/usr/bin/env python3
"""Independent check of protocol/vectors/*.hex, written from docs/protocol.md
only (no shared code with the C implementation): COBS, CRC-32C, header
fields and the payload size each message type documents."""
import glob, os, struct, sys

def crc32c(data):
    crc = 0xFFFFFFFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ (0x82F63B78 if crc & 1 else 0)
    return crc ^ 0xFFFFFFFF

def cobs_decode(enc):
    out, i = bytearray(), 0
    while i < len(enc):
        code = enc[i]; i += 1
        assert code != 0 and i + code - 1 <= len(enc), "bad COBS code"
        out += enc[i:i + code - 1]; i += code - 1
        if code != 0xFF and i < len(enc):
            out.append(0)
    return bytes(out)

# Fixed payload sizes from docs/protocol.md (None: variable, checked below),
# by wire version: v1.1 (2) has a vector per message type; v1.2 (3) the
# forms v1.1 lacks: GAP with `held`, ACK with `acked`, RCVD.
SIZES = {0x01: 28, 0x02: 4, 0x03: None, 0x04: 1, 0x05: 9, 0x06: 17, 0x07: 6,
         0x08: 2, 0x09: 1, 0x0A: 1, 0x10: 8, 0x20: 2, 0x21: 34, 0x45: 447,
         0x46: 474, 0x47: None, 0x48: None, 0x49: 15, 0x22: 4}
# v1.3: CONFIGURE is 4 bytes (Bezier) or 5 (byte 4 names the kind, 1 =
# B-spline; sizes 1..255); one vector of each form, both in wire version 2.
FORMS = {0x02: 2}
# v1.3 PUT FINE (flags 0x02: T, I, F in Q30, [0, 2^30]), in a v1.2 frame.
SIZES12 = {0x20: 10, 0x22: 12, 0x23: 2, 0x03: None}

def vector_count():
    return sum(FORMS.get(t, 1) for t in SIZES) + len(SIZES12)

def main(vdir):
    files = sorted(glob.glob(os.path.join(vdir, "*.hex")))
    assert len(files) == vector_count(), f"expected {vector_count()} vectors, got {len(files)}"
    cfg_forms = set()
    seen = set()
    for f in files:
        hexs = "".join(l for l in open(f) if not l.startswith("#"))
        wire = bytes.fromhex(hexs)
        assert wire[-1] == 0 and 0 not in wire[:-1], f"{f}: delimiter"
        raw = cobs_decode(wire[:-1])
        ver, typ, flags, _res, seq, ln = struct.unpack_from("<BBBBHH", raw)
        assert ver in (2, 3), f"{f}: version {ver} (v1.1 is wire version 2, v1.2 3)"
        assert ln == len(raw) - 12, f"{f}: length {ln} vs {len(raw) - 12}"
        (crc,) = struct.unpack_from("<I", raw, len(raw) - 4)
        assert crc == crc32c(raw[:-4]), f"{f}: CRC"
        p = raw[8:-4]
        if flags & 2 or ver == 3:  # SYN, or any v1.2 frame: u32 session, message
            (sess,) = struct.unpack_from("<I", p)
            assert sess == 0x1D2C3B4A, f"{f}: session id {sess:#x}"
            p = p[4:]
        want = (SIZES12 if ver == 3 else SIZES)[typ]
        if typ == 0x02 and len(p) == 5:
            want = 5
            assert p[4] == 1, f"{f}: CONFIGURE kind {p[4]} (5 bytes: 1 = B-spline)"
            assert 1 <= p[1] and 1 <= p[2] and not p[3] & 4, f"{f}: B-spline sizes/flags"
        if typ == 0x02:
            cfg_forms.add(len(p))
        if typ == 0x03:
            want = 4 + 52 * p[2]
        elif typ == 0x47:
            want = 13 + 48 * p[12]
        elif typ == 0x48:
            want = 7 + 48 * (p[5] + 1)
        assert len(p) == want, f"{f}: payload {len(p)} != {want}"
        if typ == 0x03:  # entry k: i, j, fp, reserved, then x, y, z, T, I, F
            assert p[1] & ~3 == 0 and p[3] == 0, f"{f}: PUT flags {p[1]:#x} (REPLACE 1, FINE 2)"
            frac = 30 if p[1] & 2 else 24
            memb = [struct.unpack_from("<q", p, 4 + 52 * e + 4 + 8 * c)[0]
                    for e in range(p[2]) for c in (3, 4, 5)]
            assert all(0 <= v <= 1 << frac for v in memb), f"{f}: memberships outside [0, 2^{frac}]"
            # the FINE vector shows what Q24 could not carry
            assert frac == 24 or any(v % 64 for v in memb), f"{f}: FINE without a membership finer than Q24"
            assert (ver == 3) == (frac == 30), f"{f}: the FINE vector is the v1.2-framed PUT"
        if ver == 3 and typ == 0x22:  # held: bit k = seq + 1 + k, never 0, has `have`
            s, have, held = struct.unpack_from("<HHQ", p)
            d = (have - s) & 0xFFFF
            assert held and 1 <= d <= 64 and held >> (d - 1) & 1, f"{f}: held {held:#x}"
        if ver == 3 and typ == 0x20:  # acked: bit k = seq - 1 - k, not 0 in the long form
            assert struct.unpack_from("<Q", p, 2)[0] != 0, f"{f}: acked 0 (the 2-byte form)"
        rel = typ not in (0x20, 0x21, 0x22, 0x23)
        assert bool(flags & 1) == rel, f"{f}: REL flag"
        if typ == 0x45:  # out_of_range bits agree with the memberships
            oor = struct.unpack_from("<I", p, 11)[0]
            for fp in range(7):
                for k in range(3):
                    (v,) = struct.unpack_from("<q", p, 15 + 48 * fp + 8 * (3 + k))
                    bit = (oor >> (3 * fp + k)) & 1
                    assert bit == (v < 0 or v > 1 << 24), f"{f}: out_of_range bit {3 * fp + k}"
        seen.add((ver, typ))
    assert seen == {(2, t) for t in SIZES} | {(3, t) for t in SIZES12}, "a message form has no vector"
    assert cfg_forms == {4, 5}, f"CONFIGURE forms with a vector: {cfg_forms}"
    doc = os.path.join(os.path.dirname(vdir.rstrip("/")), "..", "docs", "protocol.md")
    if os.path.exists(doc):  # Appendix A of the spec must show today's bytes
        text = open(doc).read()
        for f in files:
            body = "".join(l for l in open(f) if not l.startswith("#"))
            assert body in text, f"docs/protocol.md Appendix A is stale for {f}"
        # the worked example of section 3 is vector 03_commit
        commit = [f for f in files if f.endswith("03_commit.hex")][0]
        want = " ".join("".join(l for l in open(commit) if not l.startswith("#")).split())
        wl = [l for l in text.splitlines() if l.startswith("wire:  ")]
        assert wl and wl[0][7:].strip() == want, "docs/protocol.md section 3 worked example is stale"
    print(f"check_vectors: {len(files)} vectors OK")

APPX = "## Appendix A: golden vectors"
APPX_END = "ACK, NACK, GAP and RCVD have flags 0 and seq 0.\n"

def update_doc(vdir, doc):
    """Rewrite Appendix A of docs/protocol.md from the vector files."""
    text = open(doc).read()
    cut = text.index(APPX_END, text.index(APPX)) + len(APPX_END)
    out = text[:cut]
    for f in sorted(glob.glob(os.path.join(vdir, "*.hex"))):
        lines = open(f).read().splitlines()
        body = [l for l in lines if not l.startswith("#")]
        out += (f"\n### {os.path.basename(f)}\n{lines[0].lstrip('# ')}\n\n```\n"
                + "\n".join(body) + "\n```\n")
    open(doc, "w").write(out)

if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--update-doc"]
    vd = args[0] if args else "protocol/vectors"
    if "--update-doc" in sys.argv:
        update_doc(vd, os.path.join(os.path.dirname(vd.rstrip("/")), "..", "docs", "protocol.md"))
    main(vd)
