"""powercut_image.py -- the harness side of tests/daemon/powercut.c: after the
daemon is dead (SIGKILL), replace its state directory by the image a power
cut would have left, from the shim's shadow directory:

  * the namespace recorded at the last fsync of the state directory, plus
    (option prefix) a random prefix of the creates, renames and unlinks
    logged since, in their order (a journal that committed some of them);
    none of it if the state directory's own creation was never made durable
    (its parent not fsynced after the mkdir): then there is no directory;
  * each file's content as of its last fsync/fdatasync (a file never synced
    is empty);
  * option tear: a file whose live content extends its durable content
    (typically the WAL after a write whose fdatasync had not returned)
    keeps a random part of the unsynced bytes after the durable ones, as
    page writeback before the cut would leave it.

Used by tests/daemon/powercut_test.py and tests/soak/soak.py."""
import os
import shutil


def _read(path, default=None):
    try:
        with open(path, "rb") as f:
            return f.read()
    except FileNotFoundError:
        return default


def env(so, state, shadow, mode="", kill=None, skip=0, arm=None):
    """Environment entries for a daemon under the shim."""
    e = {"LD_PRELOAD": so, "IT2N_PC_STATE": state, "IT2N_PC_SHADOW": shadow, "IT2N_PC_MODE": mode}
    if kill:
        e["IT2N_PC_KILL"] = kill
        e["IT2N_PC_KILL_SKIP"] = str(skip)
        if arm:
            e["IT2N_PC_ARM"] = arm
    return e


def killed_at(shadow):
    """The event at which the shim killed the daemon, or None."""
    k = _read(os.path.join(shadow, "killed"))
    return k.decode().strip() if k else None


def events(shadow):
    e = _read(os.path.join(shadow, "events"), b"")
    return e.decode(errors="replace").split()


def _apply(ns, ops):
    ns = dict(ns)
    for op in ops:
        if op[0] == "C":
            ns[op[2]] = op[1]
        elif op[0] == "R":
            if op[1] in ns:
                ns[op[2]] = ns.pop(op[1])
        elif op[0] == "U":
            ns.pop(op[1], None)
    return ns


def rollback(state, shadow, rnd, prefix=False, tear=False):
    """Roll state back to the durable image (the daemon must be dead).
    Returns a description: {"dir": bool, "files": {name: size}, "ops_pending",
    "ops_kept", "torn": {name: bytes kept beyond the durable content}}."""
    dir_ok = (_read(os.path.join(shadow, "dir"), b"0").strip() == b"1")
    lines = _read(os.path.join(shadow, "ns"), b"offset 0\n").decode().splitlines()
    offset = int(lines[0].split()[1])
    ns = {}
    for ln in lines[1:]:
        i, name = ln.split(" ", 1)
        ns[name] = int(i)
    oplog = _read(os.path.join(shadow, "oplog"), b"")[offset:].decode().splitlines()
    ops = []
    for ln in oplog:
        p = ln.split(" ")
        ops.append((p[0], int(p[1]), p[2]) if p[0] == "C" else tuple(p))
    keep = rnd.randint(0, len(ops)) if prefix and ops else 0
    durable = _apply(ns, ops[:keep])
    live = _apply(ns, ops)
    live_name = {i: n for n, i in live.items()}
    image, torn = {}, {}
    for name, i in durable.items():
        data = _read(os.path.join(shadow, "d", str(i)), b"")
        if tear and i in live_name:
            cur = _read(os.path.join(state, live_name[i]), b"")
            extra = len(cur) - len(data)
            if extra > 0 and cur.startswith(data) and rnd.random() < 0.5:
                n = rnd.randint(1, extra)
                data = cur[:len(data) + n]
                torn[name] = n
        image[name] = data
    if os.path.isdir(state):
        shutil.rmtree(state)
    if dir_ok:
        os.mkdir(state, 0o750)
        for name, data in image.items():
            with open(os.path.join(state, name), "wb") as f:
                f.write(data)
    return {"dir": dir_ok, "files": {n: len(d) for n, d in image.items()} if dir_ok else {},
            "ops_pending": len(ops), "ops_kept": keep, "torn": torn if dir_ok else {}}
