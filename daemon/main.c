/* it2nd — serves firmware_core models over Modbus TCP/RTU and takes data
 * points from instruments on serial/USB links. See docs/daemon.md. */
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <grp.h>
#include <pwd.h>
#include <netdb.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include "conf.h"
#include "conf_schema.h"
#include "links.h"
#include "log.h"
#include "loop.h"
#include "mb_rtu.h"
#include "mb_tcp.h"
#include "metrics.h"
#include "models.h"
#include "notify.h"
#include "spb.h"
#include "porthint.h"
#include "store.h"

/* The project's version, from the file VERSION (the Makefile passes it). */
#ifndef IT2N_VERSION
#error "IT2N_VERSION undefined: build with the top-level Makefile (-DIT2N_VERSION from VERSION)"
#endif
#define IT2ND_VERSION IT2N_VERSION

static volatile sig_atomic_t sig_stop, sig_reload;
static int sig_pipe[2] = {-1, -1};
static struct conf cfg;
static const char *conf_path;
static struct conf_override ovr; /* --listen, --state-dir, --metrics */
static struct mb_map_opts mbo;
static long snap_timer, wd_timer, recover_timer;
static int snap_due, recover_due;

static void on_signal(int sig)
{
    int saved = errno;
    if (sig == SIGHUP)
        sig_reload = 1;
    else
        sig_stop = 1;
    if (write(sig_pipe[1], "s", 1) < 0) {
        /* pipe full: the flag is set, the loop will see it */
    }
    errno = saved;
}

static void on_sig_pipe(void *arg, int fd, short revents)
{
    char buf[64];
    (void)arg;
    (void)revents;
    while (read(fd, buf, sizeof buf) > 0) {
    }
}

static void usage(FILE *f)
{
    fprintf(f, "usage: it2nd [-c FILE] [--listen HOST:PORT] [--state-dir DIR] [--metrics HOST:PORT]\n"
               "             [--check-config] [--config-keys[=FORMAT]] [--accept-wal-loss] [--foreground]\n"
               "             [-v...] [--help] [--version]\n"
               "  -c, --config FILE     configuration (INI); default: built-in (Modbus TCP\n"
               "                        127.0.0.1:1502, model 1 on unit 1 with the paper data)\n"
               "  -l, --listen HOST:PORT  Modbus TCP address (repeatable); replaces the\n"
               "                        file's listeners ([modbus] tcp_listen, [listen:NAME])\n"
               "  -s, --state-dir DIR   state directory (WAL, snapshot); overrides state_dir\n"
               "  -m, --metrics HOST:PORT  Prometheus endpoint (GET /metrics), or none;\n"
               "                        overrides [metrics] listen (default: off)\n"
               "  -t, --check-config    validate the configuration, check that the state\n"
               "                        directory is writable and the ports free, and exit\n"
               "  --config-keys[=FORMAT]  print every section and key of the configuration\n"
               "                        (type, range, default, reload, help) and exit; FORMAT\n"
               "                        text (default), markdown or dict (a fuzzer dictionary)\n"
               "  --accept-wal-loss     the operator's act after damage inside the WAL: cut the\n"
               "                        WAL at the damaged record (the rest kept in wal.cut-*),\n"
               "                        log the records given up, and exit (docs/daemon.md)\n"
               "  -f, --foreground      log to stderr (default when not started by systemd: syslog)\n"
               "  -v, --verbose         more logging (-vv debug)\n"
               "  -h, --help            this text\n"
               "  -V, --version         print the version\n");
}

static void fill_opts(void)
{
    mbo.word_order = cfg.word_order;
    mbo.int32_order = cfg.int32_word_order < 0 ? cfg.word_order : cfg.int32_word_order;
    mbo.default_unit = conf_default_unit(&cfg);
    mbo.coord_scale = cfg.coord_scale;
    mbo.grid_rows = (unsigned)cfg.grid_rows;
    mbo.grid_cols = (unsigned)cfg.grid_cols;
    memset(mbo.write_protect, 0, sizeof mbo.write_protect);
    for (int k = 0; k < cfg.nmodels; k++)
        if (cfg.model[k].write_protect)
            mbo.write_protect[cfg.model[k].unit / 8] |= (uint8_t)(1u << (cfg.model[k].unit % 8));
}

static int load_conf(struct conf *c)
{
    static int warned;
    char err[512];
    int policies = 0;
    conf_default(c);
    if (conf_path && conf_load(c, conf_path, err, sizeof err)) {
        log_err("%s", err);
        return -1;
    }
    for (int k = 0; k < c->nlisten; k++)
        policies += c->listen[k].nallow > 0 || c->listen[k].read_only;
    if (conf_apply_override(c, &ovr, err, sizeof err) || conf_check_devices(c, conf_path, err, sizeof err) ||
        conf_check_hosts(c, conf_path, err, sizeof err) || spb_tls_check(&c->spb, conf_path, err, sizeof err)) {
        log_err("%s", err);
        return -1;
    }
    /* --listen replaces the file's listeners, access policy included:
     * say so once rather than widen access silently. */
    if (ovr.nlisten && policies && !warned++)
        log_warn("--listen replaces the listeners of %s, %d of them with an access policy (allow, read_only): "
                 "the --listen address%s ha%s none",
                 conf_path, policies, ovr.nlisten > 1 ? "es" : "", ovr.nlisten > 1 ? "ve" : "s");
    return 0;
}

/* One line per model with its actual state (after the WAL replay at
 * start, so a restored model never shows up as "empty" first). */
static void log_model(const struct model *md, const char *why)
{
    static const char *const st[] = {"empty", "incomplete", "solved", "solve failed"};
    unsigned need = models_required(md);
    unsigned missing = models_missing(md);
    log_info("model %d on unit %d: %s %ux%u, flags %u, %s, %u/%u points, generation %u%s", md->id, md->unit,
             models_kind_name(md->kind), models_n(md), models_m(md), models_flags(md),
             md->state >= 0 && md->state <= 3 ? st[md->state] : "?", need - missing, need, (unsigned)md->gen, why);
}

static int add_model(const struct conf_model *m, int at_start)
{
    struct model *md = models_add(m->id, m->unit, m->kind, (unsigned)m->n, (unsigned)m->m, m->flags);
    if (!md) {
        log_err("model %d: cannot create (%s %dx%d: %zu bytes)", m->id, models_kind_name(m->kind), m->n, m->m,
                models_bytes(m->kind, (unsigned)m->n, (unsigned)m->m));
        return -1;
    }
    if (m->preload) {
        int rc = models_preload_paper(md);
        if (rc != IT2N_OK) {
            log_err("model %d: paper data set does not load: %s", m->id, it2n_strerror(rc));
            models_remove(md);
            return -1;
        }
    }
    if (!at_start) /* at start: logged once the WAL is replayed */
        log_model(md, m->preload ? " (paper data preloaded)" : "");
    return 0;
}

static int setup_models(void)
{
    /* Room for the most a reload may configure; max_models is checked by
     * the configuration. */
    if (models_init(CONF_MAX_MODELS))
        return -1;
    for (int k = 0; k < cfg.nmodels; k++)
        if (add_model(&cfg.model[k], 1))
            return -1;
    return 0;
}

/* A model changed durably: tell the link peers (links.c coalesces). */
static void on_model_changed(void *arg, const struct model *md, int old_state, uint32_t old_gen)
{
    (void)arg;
    if (md->gen != old_gen && md->state == IT2N_REGMAP_STATE_SOLVED)
        log_info("model %d: solved, generation %u", md->id, (unsigned)md->gen);
    else if (md->state != old_state && md->state == IT2N_REGMAP_STATE_FAILED)
        log_info("model %d: solve failed: %s", md->id, it2n_strerror(md->last_err.code));
    else if (md->state != old_state)
        log_info("model %d: %s", md->id, md->state == IT2N_REGMAP_STATE_EMPTY ? "cleared" : "points missing");
    links_event(md, old_state);
    spb_model_changed(md->id);
}

/* The store is degraded (an I/O error): try a checkpoint every second. */
static void on_recover(void *arg)
{
    (void)arg;
    recover_timer = 0;
    recover_due = 1; /* taken by commit_hook, when memory equals what was acknowledged */
}

static void release_upto(uint64_t batch, int ok)
{
    mb_tcp_release_upto(batch, ok);
    mb_rtu_release_upto(batch, ok);
    links_release_upto(batch, ok);
}

static void arm_recover(void)
{
    if (store_degraded() && !recover_timer)
        recover_timer = loop_add_timer(1000, on_recover, NULL);
}

/* Hand the next job to the writer thread when it is idle (the hook after
 * every loop pass, and after every job done): a checkpoint when one is
 * due, else every WAL record gathered since the last hand-off as one
 * batch (group commit: one write + one fdatasync on the writer thread).
 * The loop goes on serving meanwhile; the batch's replies and ACKs wait
 * for it (on_writer_done). */
static void kick(void)
{
    if (store_busy())
        return;
    if (store_pending() && store_degraded()) {
        /* Refused without I/O: put back, answer 04 / NACK. */
        store_submit(NULL);
        models_pass_end(0, NULL, NULL);
        release_upto(UINT64_MAX, 0);
    }
    if (snap_due) {
        snap_due = 0;
        if (store_wal_bytes() > 0 && store_submit_checkpoint() > 0)
            return;
    }
    /* Degraded (a failed commit, an unsynced WAL rename): no write is
     * accepted until a checkpoint of the durable state succeeds. */
    if (recover_due && store_degraded()) {
        recover_due = 0;
        if (store_submit_checkpoint() > 0)
            return;
    }
    if (store_pending()) {
        models_batch_submit();
        if (store_submit(NULL) > 0)
            return;
        /* cannot happen (idle, not degraded); fail safe */
        models_batch_done(0, NULL, NULL);
        release_upto(UINT64_MAX, 0);
    } else if (models_pass_dirty()) {
        /* Changes refused or undone in the pass: nothing to write. */
        models_pass_end(1, on_model_changed, NULL);
    }
    arm_recover();
}

/* A job is done. A commit: its changes are durable, announced, and its
 * replies and ACKs go out; or it failed, and every model touched by it or
 * by the batch gathered since is put back (their records are dropped, the
 * store is degraded), so the exception 04 / NACK that follows means
 * "nothing changed". */
static void on_done(const struct store_done *d)
{
    if (d->kind == STORE_DONE_COMMIT) {
        if (d->us > 100000)
            log_debug("wal: group commit took %llu ms", (unsigned long long)(d->us / 1000));
        models_batch_done(d->ok, on_model_changed, NULL);
        spb_batch_done(); /* every durable change, not only state/generation moves */
        release_upto(d->ok ? d->batch : UINT64_MAX, d->ok);
    }
    arm_recover();
}

static void on_writer(void *arg, int fd, short revents)
{
    struct store_done d;
    (void)arg;
    (void)fd;
    (void)revents;
    if (store_reap(&d))
        on_done(&d);
    kick();
}

static void commit_hook(void *arg)
{
    (void)arg;
    kick();
}

/* Synchronously: everything in flight and gathered made durable and
 * answered (reload, shutdown; the loop waits for the disk here only). */
static void drain(void)
{
    struct store_done d;
    for (int k = 0; k < 1000; k++) {
        if (store_busy()) {
            store_wait();
            if (store_reap(&d))
                on_done(&d);
            continue;
        }
        if (!store_pending() && !models_pass_dirty())
            return;
        kick();
    }
}

/* chrony style: everything that needs root (listeners, RTU ports, the
 * state directory) is open; give the state directory to the user, take
 * its groups (dialout for serial links opened later), then its gid and
 * uid, and make sure root cannot come back. */
static int drop_privileges(void)
{
    if (!cfg.user[0]) {
        if (geteuid() == 0)
            log_warn("running as root: set user = NAME in [daemon] to drop root once the listeners and "
                     "ports are open (not needed under the systemd unit, which uses DynamicUser=)");
        return 0;
    }
    if (geteuid() != 0) {
        log_notice("user = %s: not running as root, nothing to drop", cfg.user);
        return 0;
    }
    uid_t uid = (uid_t)cfg.uid;
    gid_t gid = (gid_t)cfg.gid;
    if (store_chown(cfg.uid, cfg.gid)) {
        log_err("user %s: cannot chown %s: %s", cfg.user, cfg.state_dir, strerror(errno));
        return -1;
    }
    if (initgroups(cfg.user, gid) || setgid(gid) || setuid(uid)) {
        log_err("user %s: cannot switch to uid %u gid %u: %s", cfg.user, cfg.uid, cfg.gid, strerror(errno));
        return -1;
    }
    if (uid != 0 && (setuid(0) == 0 || seteuid(0) == 0 || getuid() != uid || geteuid() != uid || getgid() != gid ||
                     getegid() != gid)) {
        log_err("user %s: root privileges could be regained; refusing to run", cfg.user);
        return -1;
    }
    log_notice("running as user %s (uid %u, gid %u)", cfg.user, cfg.uid, cfg.gid);
    return 0;
}

static void send_status(void)
{
    char buf[256];
    struct store_stats st;
    uint32_t pts = 0, req = 0;
    int solved = 0;
    store_get_stats(&st);
    for (int k = 0; k < models_count(); k++) {
        const struct model *md = models_at(k);
        pts += md->points_rx;
        req += md->mb.requests;
        solved += md->state == IT2N_REGMAP_STATE_SOLVED;
    }
    snprintf(buf, sizeof buf,
             "STATUS=%d/%d models solved, %d tcp clients, %d links up, %u requests, %u points, %llu wal records",
             solved, models_count(), mb_tcp_clients(), links_up(), req, pts, (unsigned long long)st.records);
    notify_send(buf);
}

static void on_snapshot(void *arg)
{
    (void)arg;
    snap_due = 1; /* taken by commit_hook, after this pass is durable */
    send_status();
    snap_timer = loop_add_timer((uint64_t)cfg.snapshot_interval * 1000u, on_snapshot, NULL);
}

static void on_watchdog(void *arg)
{
    (void)arg;
    notify_send("WATCHDOG=1");
    wd_timer = loop_add_timer(notify_watchdog_ms() / 2, on_watchdog, NULL);
}

static const struct conf_model *conf_model_by_id(const struct conf *c, int id)
{
    for (int k = 0; k < c->nmodels; k++)
        if (c->model[k].id == id)
            return &c->model[k];
    return NULL;
}

/* At start: the state's data of a model without a [model:] section are
 * dropped only when its section says removed = yes. */
static int may_drop(int id)
{
    return conf_removes(&cfg, id);
}

/* A reload never discards data as a side effect of the file (a section
 * lost in a rewrite): a running model that holds points and has no
 * [model:] section in the new file refuses the whole reload, unless its
 * section says removed = yes (the operator's explicit act). Logged, one
 * line per model; returns how many there are. */
static int removals_refused(const struct conf *nc)
{
    int refused = 0;
    for (int k = 0; k < models_count(); k++) {
        const struct model *md = models_at(k);
        unsigned pts = models_present(md);
        if (!pts || conf_model_by_id(nc, md->id) || conf_removes(nc, md->id))
            continue;
        log_err("reload refused: model %d (unit %d) holds %u data point(s) (generation %u) but %s has no [model:%d] "
                "section; to discard its data on purpose keep the section with 'removed = yes' (docs/daemon.md)",
                md->id, md->unit, pts, (unsigned)md->gen, conf_path ? conf_path : "the configuration", md->id);
        refused++;
    }
    return refused;
}

/* The same for a change of degree or flags (a CONFIGURE, clearing the
 * points) that comes from a default because the file no longer gives the
 * key (a line lost at the end of a cut file): only a key the file gives
 * reconfigures a model holding data. Returns how many models refuse. */
static int reconfigures_refused(const struct conf *nc)
{
    static const struct {
        unsigned set, flag;
        const char *key;
    } keys[] = {
        {CONF_SET_Z, IT2N_F_Z, "z"},
        {CONF_SET_TYPE1, IT2N_F_TYPE1, "type1"},
        {CONF_SET_CHORD, IT2N_F_CHORD, "chord"},
    };
    int refused = 0;
    for (int k = 0; k < models_count(); k++) {
        const struct model *md = models_at(k);
        const struct conf_model *m = conf_model_by_id(nc, md->id), *old = conf_model_by_id(&cfg, md->id);
        unsigned pts = models_present(md);
        char lost[64] = "";
        size_t len = 0;
        if (!pts || !m || !old)
            continue;
        if (old->kind != m->kind && !(m->set & CONF_SET_KIND))
            len += (size_t)snprintf(lost + len, sizeof lost - len, "%skind", len ? ", " : "");
        if (old->n != m->n && !(m->set & CONF_SET_N))
            len += (size_t)snprintf(lost + len, sizeof lost - len, "%sn", len ? ", " : "");
        if (old->m != m->m && !(m->set & CONF_SET_M))
            len += (size_t)snprintf(lost + len, sizeof lost - len, "%sm", len ? ", " : "");
        for (size_t b = 0; b < sizeof keys / sizeof keys[0]; b++)
            if (((old->flags ^ m->flags) & keys[b].flag) && !(m->set & keys[b].set))
                len += (size_t)snprintf(lost + len, sizeof lost - len, "%s%s", len ? ", " : "", keys[b].key);
        if (!len)
            continue;
        log_err("reload refused: model %d (unit %d) holds %u data point(s) (generation %u) and [model:%d] in %s no "
                "longer gives %s: its default would reconfigure the model and clear them; write the key to reconfigure "
                "on purpose (docs/daemon.md)",
                md->id, md->unit, pts, (unsigned)md->gen, md->id, conf_path ? conf_path : "the configuration", lost);
        refused++;
    }
    return refused;
}

/* Apply [model:] changes of a reload to the live table (no pass in
 * progress): removed models go (removals_refused() has made sure the data
 * of each was either nothing or given up with removed = yes; a snapshot
 * right after makes sure no WAL record of theirs is left to replay at
 * restart), unit ids re-map, a changed degree/flags is a journaled
 * CONFIGURE (points cleared), new models appear (preloaded if asked). */
static void reload_models(const struct conf *nc)
{
    int removed = 0;
    for (int k = models_count() - 1; k >= 0; k--) {
        struct model *md = models_at(k);
        if (!conf_model_by_id(nc, md->id)) {
            unsigned pts = models_present(md);
            if (pts)
                log_notice("reload: model %d (unit %d) removed (removed = yes); its %u data point(s) are discarded",
                           md->id, md->unit, pts);
            else
                log_notice("reload: model %d (unit %d) removed; it held no data points", md->id, md->unit);
            models_remove(md);
            removed++;
        }
    }
    /* All kept models take their new unit at once: swaps never collide. */
    for (int k = 0; k < models_count(); k++) {
        struct model *md = models_at(k);
        const struct conf_model *m = conf_model_by_id(nc, md->id);
        if (m->unit != md->unit) {
            log_notice("reload: model %d moves from unit %d to unit %d", md->id, md->unit, m->unit);
            md->unit = m->unit;
        }
    }
    for (int k = 0; k < models_count(); k++) {
        struct model *md = models_at(k);
        const struct conf_model *m = conf_model_by_id(nc, md->id);
        const struct conf_model *old = conf_model_by_id(&cfg, md->id);
        it2n_errinfo err;
        /* Only a change of the configuration file reconfigures: a model a
         * link or PLC reconfigured keeps its data while its section stays. */
        if (!old || (old->n == m->n && old->m == m->m && old->flags == m->flags && old->kind == m->kind))
            continue;
        if (m->kind != md->kind || (md->kind == MODEL_BSPLINE && (m->n > (int)md->cap_n || m->m > (int)md->cap_m))) {
            /* Another kind, or a B-spline grid beyond the model's storage:
             * a new model in place of the old one (its points were cleared
             * by a CONFIGURE anyway; the snapshot below drops its WAL
             * records). */
            log_notice("reload: model %d replaced by a %s model of %dx%d (%zu bytes): points cleared", md->id,
                       models_kind_name(m->kind), m->n, m->m, models_bytes(m->kind, (unsigned)m->n, (unsigned)m->m));
            models_remove(md);
            k--;
            removed++;
            continue; /* added back below */
        }
        if (models_configure(md, (unsigned)m->n, (unsigned)m->m, m->flags, &err) == IT2N_OK)
            log_notice("reload: model %d reconfigured to %dx%d, flags %u: points cleared (journaled CONFIGURE)", md->id,
                       m->n, m->m, m->flags);
        else
            log_err("reload: model %d cannot be reconfigured: %s", md->id, it2n_strerror(err.code));
    }
    for (int k = 0; k < nc->nmodels; k++)
        if (!models_by_id(nc->model[k].id)) {
            log_notice("reload: model %d added on unit %d", nc->model[k].id, nc->model[k].unit);
            add_model(&nc->model[k], 0);
        }
    drain(); /* the CONFIGUREs: durable, announced, or rolled back */
    if (removed && store_snapshot())
        log_err("reload: snapshot after removing models failed; their WAL records are skipped at restart");
}

static void reload(void)
{
    struct conf nc;
    log_notice("reloading configuration");
    notify_send("RELOADING=1");
    if (load_conf(&nc)) {
        log_err("reload failed; keeping the running configuration");
        notify_send("READY=1");
        return;
    }
    /* Finish the pass in progress first (replies released during the last
     * commit may have started another): models are only added or removed
     * when nothing refers to them. */
    drain();
    if (store_busy() || store_pending() || models_pass_dirty()) {
        log_warn("reload postponed: writes in progress");
        sig_reload = 1;
        return;
    }
    if (removals_refused(&nc) + reconfigures_refused(&nc)) {
        log_err("reload failed; keeping the running configuration");
        notify_send("READY=1");
        return;
    }
    if (strcmp(nc.state_dir, cfg.state_dir)) {
        log_warn("reload: state_dir change (%s -> %s) takes effect at restart", cfg.state_dir, nc.state_dir);
        snprintf(nc.state_dir, sizeof nc.state_dir, "%s", cfg.state_dir);
    }
    if (strcmp(nc.metrics.host, cfg.metrics.host) || strcmp(nc.metrics.port, cfg.metrics.port)) {
        log_warn("reload: [metrics] listen change (%s -> %s%s%s) takes effect at restart",
                 metrics_address()[0] ? metrics_address() : "off", nc.metrics.port[0] ? nc.metrics.host : "off",
                 nc.metrics.port[0] ? ":" : "", nc.metrics.port);
        nc.metrics = cfg.metrics;
    }
    if (strcmp(nc.user, cfg.user)) {
        log_warn("reload: user change takes effect at restart");
        memcpy(nc.user, cfg.user, sizeof nc.user);
        nc.uid = cfg.uid;
        nc.gid = cfg.gid;
    }
    if (nc.io != cfg.io) {
        log_warn("reload: io change takes effect at restart (now %s)", loop_io_name());
        nc.io = cfg.io;
    }
    reload_models(&nc);
    if (nc.fsync != cfg.fsync)
        log_notice("reload: fsync %s", nc.fsync ? "on: WAL writes are fsynced again" : "off (tests only)");
    store_set_fsync(nc.fsync);
    cfg = nc;
    fill_opts();
    mb_tcp_reload(&cfg, &mbo);
    mb_rtu_reload(&cfg, &mbo);
    links_reload(&cfg);
    spb_reload(&cfg);
    loop_cancel_timer(snap_timer);
    snap_timer = loop_add_timer((uint64_t)cfg.snapshot_interval * 1000u, on_snapshot, NULL);
    notify_send("READY=1");
    log_notice("configuration reloaded (%d models)", models_count());
}

/* --check-config: whether a running it2nd holds state_dir's lock (then
 * the ports it listens on are expected to be in use). */
static int state_dir_in_use(const char *dir)
{
    char path[CONF_PATH + 8];
    int fd, busy = 0;
    snprintf(path, sizeof path, "%s/lock", dir);
    fd = open(path, O_RDONLY | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK);
    if (fd < 0)
        return 0;
    if (flock(fd, LOCK_SH | LOCK_NB) && errno == EWOULDBLOCK)
        busy = 1;
    close(fd); /* releases a shared lock taken just now */
    return busy;
}

/* --check-config: a file can be created in dir (then removed); access()
 * would say yes to root on a read-only mount. Returns 0 or errno. */
static int try_write(const char *dir)
{
    char path[CONF_PATH + 32];
    int fd;
    snprintf(path, sizeof path, "%s/.it2nd-check-XXXXXX", dir);
    fd = mkstemp(path);
    if (fd < 0)
        return errno;
    close(fd);
    unlink(path);
    return 0;
}

/* --check-config: the daemon could create and write state_dir, tried the
 * way store_open does it: an existing directory gets a file created and
 * removed; a missing one is created (one mkdir: the daemon creates the
 * last component only) for the test and removed again, so the check
 * leaves nothing behind. Returns 0 or -1 (logged). */
static int check_state_dir(const char *dir)
{
    struct stat st;
    int made = 0, e = 0;
    const char *who = cfg.user[0] ? cfg.user : "the user it2nd runs as";
    if (stat(dir, &st) == 0 && !S_ISDIR(st.st_mode)) {
        log_err("state_dir %s: exists and is not a directory; choose another (state_dir or --state-dir)", dir);
        return -1;
    }
    if (stat(dir, &st) != 0 && errno != ENOENT) {
        log_err("state_dir %s: %s; the daemon could not use it: make it reachable by %s or choose another "
                "(state_dir or --state-dir)",
                dir, strerror(errno), who);
        return -1;
    }
    if (stat(dir, &st) != 0) {
        if (mkdir(dir, 0750) == 0) {
            made = 1;
        } else {
            e = errno;
            log_err("state_dir %s: cannot be created: %s%s; create it (writable by %s) or choose another (state_dir "
                    "or --state-dir)",
                    dir, strerror(e),
                    e == ENOENT ? " (its parent directory does not exist; "
                                  "it2nd creates the last component only)"
                                : "",
                    who);
        }
    }
    if (!e && (e = try_write(dir)) != 0)
        log_err("state_dir %s: not writable (creating a file: %s); the daemon could not keep its WAL there: make it "
                "writable by %s or choose another (state_dir or --state-dir)",
                dir, strerror(e), who);
    if (made)
        rmdir(dir);
    return e ? -1 : 0;
}

/* --check-config: bind host:port now (then close). In use: an error, or
 * only a warning while a running it2nd holds this state_dir (it is the
 * daemon being checked before a reload or restart). Returns 0 or -1. */
static int check_port(const char *what, const char *host, const char *port, const char *flag, int running)
{
    struct addrinfo hints, *res = NULL, *ai;
    int rc, e = 0, v6 = strchr(host, ':') != NULL;
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
    rc = getaddrinfo(host[0] ? host : NULL, port, &hints, &res);
    if (rc)
        return 0; /* conf_check_hosts has said it */
    for (ai = res; ai; ai = ai->ai_next) {
        int one = 1, fd = socket(ai->ai_family, ai->ai_socktype | SOCK_CLOEXEC, 0);
        if (fd < 0)
            continue;
        setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
        if (ai->ai_family == AF_INET6)
            setsockopt(fd, IPPROTO_IPV6, IPV6_V6ONLY, &one, sizeof one);
        if (bind(fd, ai->ai_addr, ai->ai_addrlen) && !e)
            e = errno;
        close(fd);
    }
    freeaddrinfo(res);
    if (!e)
        return 0;
    if (e == EADDRINUSE) {
        char hint[320];
        if (running) {
            porthint_holder(atoi(port), hint, sizeof hint);
            log_warn("%s %s%s%s:%s: in use%s%s while a running it2nd holds %s/lock: presumably that daemon's own "
                     "listener (not an error)",
                     what, v6 ? "[" : "", host, v6 ? "]" : "", port, hint[0] ? " by " : "", hint, cfg.state_dir);
            return 0;
        }
        porthint_in_use(host, port, flag, hint, sizeof hint);
        log_err("%s: %s", what, hint);
        return -1;
    }
    log_err("%s %s%s%s:%s: cannot bind: %s%s", what, v6 ? "[" : "", host, v6 ? "]" : "", port, strerror(e),
            e == EACCES          ? " (ports below 1024 need root or CAP_NET_BIND_SERVICE)"
            : e == EADDRNOTAVAIL ? " (no such local address)"
                                 : "");
    return -1;
}

static int check_runtime(void)
{
    int bad = 0, running = state_dir_in_use(cfg.state_dir);
    if (running)
        log_warn("state_dir %s: locked by a running it2nd (fine when checking before a reload; a second daemon "
                 "on it would refuse to start)",
                 cfg.state_dir);
    else
        bad |= check_state_dir(cfg.state_dir);
    for (int k = 0; k < cfg.nlisten; k++)
        bad |= check_port("modbus tcp listen", cfg.listen[k].host, cfg.listen[k].port,
                          "it2nd --listen HOST:PORT, or tcp_listen / address in the configuration", running);
    if (cfg.metrics.port[0])
        bad |= check_port("metrics listen", cfg.metrics.host, cfg.metrics.port,
                          "it2nd --metrics HOST:PORT, or [metrics] listen", running);
    return bad ? -1 : 0;
}

int main(int argc, char **argv)
{
    static const struct option lopts[] = {{"config", required_argument, NULL, 'c'},
                                          {"check-config", no_argument, NULL, 't'},
                                          {"foreground", no_argument, NULL, 'f'},
                                          {"verbose", no_argument, NULL, 'v'},
                                          {"help", no_argument, NULL, 'h'},
                                          {"version", no_argument, NULL, 'V'},
                                          {"accept-wal-loss", no_argument, NULL, 'A'},
                                          {"listen", required_argument, NULL, 'l'},
                                          {"state-dir", required_argument, NULL, 's'},
                                          {"metrics", required_argument, NULL, 'm'},
                                          {"config-keys", optional_argument, NULL, 'K'},
                                          {NULL, 0, NULL, 0}};
    int opt, check = 0, fg = 0, verbose = 0, accept_loss = 0;
    while ((opt = getopt_long(argc, argv, "c:tfvhVl:s:m:", lopts, NULL)) != -1) {
        switch (opt) {
        case 'c': conf_path = optarg; break;
        case 'l':
            if (ovr.nlisten == CONF_MAX_LISTEN) {
                fprintf(stderr, "it2nd: --listen: at most %d addresses\n", CONF_MAX_LISTEN);
                return 2;
            }
            ovr.listen[ovr.nlisten++] = optarg;
            break;
        case 's': ovr.state_dir = optarg; break;
        case 'm': ovr.metrics = optarg; break;
        case 't': check = 1; break;
        case 'f': fg = 1; break;
        case 'v': verbose++; break;
        case 'h': usage(stdout); return 0;
        case 'A': accept_loss = 1; break;
        case 'K':
            if (conf_schema_print(stdout, optarg ? optarg : "text")) {
                fprintf(stderr, "it2nd: --config-keys=%s: expected text, markdown or dict\n", optarg);
                return 2;
            }
            return fflush(stdout) ? 1 : 0;
        case 'V': printf("it2nd %s (register map %u)\n", IT2ND_VERSION, IT2N_REGMAP_VERSION); return 0;
        default: usage(stderr); return 2;
        }
    }
    if (optind != argc) {
        usage(stderr);
        return 2;
    }
    log_open(fg || check || accept_loss, verbose);
    if (load_conf(&cfg))
        return 1;
    if (check) {
        if (check_runtime())
            return 1;
        printf("%s%s: configuration OK (%d listen, %d rtu, %d models, %d links", conf_path ? conf_path : "built-in",
               ovr.nlisten || ovr.state_dir || ovr.metrics ? " with flags" : "", cfg.nlisten, cfg.nrtu, cfg.nmodels,
               cfg.nlinks);
        for (int k = 0; k < cfg.nremoved; k++)
            printf("%s%d", k ? ", " : "; removed = yes: model ", cfg.removed[k]);
        printf("%s)\n", cfg.metrics.port[0] ? ", metrics" : "");
        return 0;
    }
    notify_init();
    if (loop_init((enum loop_io)cfg.io)) {
        log_err("io = io_uring: the kernel refuses io_uring (%s); set io = auto or epoll in [daemon]", strerror(errno));
        return 1;
    }
    log_notice("I/O: %s%s", loop_io_name(),
               cfg.io == LOOP_IO_AUTO && strcmp(loop_io_name(), "io_uring") ? " (io = auto: io_uring refused)" : "");

    if (pipe2(sig_pipe, O_NONBLOCK | O_CLOEXEC))
        return 1;
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGHUP, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);
    loop_add_fd(sig_pipe[0], POLLIN, on_sig_pipe, NULL);

    fill_opts();
    if (setup_models())
        return 1;
    store_set_drop_policy(may_drop);
    store_accept_wal_loss(accept_loss);
    if (store_open(cfg.state_dir, cfg.fsync))
        return 1;
    if (accept_loss) {
        /* One shot, with the service stopped (the state directory's lock
         * is taken): the WAL now ends before the damage; nothing served. */
        store_close();
        models_free();
        log_notice("--accept-wal-loss: %s/wal is valid to its end now; start the daemon as usual", cfg.state_dir);
        return 0;
    }
    for (int k = 0; k < models_count(); k++)
        log_model(models_at(k), "");
    models_set_journal(store_append, NULL);
    models_set_journal_marks(store_jmark, store_jrewind);
    int wfd = store_start_writer();
    if (wfd < 0 || loop_add_fd(wfd, POLLIN, on_writer, NULL)) {
        log_err("cannot start the writer thread: %s", strerror(errno));
        return 1;
    }
    loop_add_hook(commit_hook, NULL);
    if (mb_tcp_start(&cfg, &mbo) || mb_rtu_start(&cfg, &mbo)) {
        log_err("no Modbus endpoint could be opened");
        return 1;
    }
    if (metrics_start(&cfg))
        return 1;
    links_start(&cfg);
    if (drop_privileges())
        return 1;
    if (spb_start(&cfg, IT2ND_VERSION))
        return 1;
    snap_timer = loop_add_timer((uint64_t)cfg.snapshot_interval * 1000u, on_snapshot, NULL);
    if (notify_watchdog_ms())
        wd_timer = loop_add_timer(notify_watchdog_ms() / 2, on_watchdog, NULL);
    notify_send("READY=1");
    send_status();
    log_notice("it2nd %s ready (%d models)", IT2ND_VERSION, models_count());
    log_started();

    while (!sig_stop) {
        if (sig_reload) {
            sig_reload = 0;
            reload();
        }
        if (loop_run_once(-1)) {
            log_err("poll: %s", strerror(errno));
            break;
        }
    }
    notify_send("STOPPING=1");
    log_notice("stopping: flushing state");
    drain();
    spb_stop(); /* after drain: its changes go out as DDATA before the NDEATH */
    metrics_stop();
    links_stop();
    mb_rtu_stop();
    mb_tcp_stop();
    /* A clean stop that cannot write its snapshot says so in the exit
     * status (no temporary file is left; what was acknowledged is still in
     * the last snapshot and the WAL). */
    int rc = 0;
    if (store_snapshot()) {
        log_err("stopping: the final snapshot could not be written; exit status 1 (the acknowledged state is in "
                "%s: the last snapshot and the WAL)",
                cfg.state_dir);
        rc = 1;
    }
    store_close();
    models_free();
    loop_free();
    return rc;
}
