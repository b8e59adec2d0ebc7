/* test_conf — configuration: defaults, every section kind, and fatal
 * errors naming file:line: [section] key. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include "conf.h"
#include "conf_schema.h"
#include "it2n.h"

static char path[64];

static int load_n(const char *text, size_t n, struct conf *c, char *err, size_t size)
{
    FILE *f;
    snprintf(path, sizeof path, "/tmp/it2nd-test-conf.%d.ini", (int)getpid());
    f = fopen(path, "w");
    assert_non_null(f);
    assert_int_equal(fwrite(text, 1, n, f), n);
    fclose(f);
    conf_default(c);
    int rc = conf_load(c, path, err, size);
    unlink(path);
    return rc;
}

static int load(const char *text, struct conf *c, char *err, size_t size)
{
    return load_n(text, strlen(text), c, err, size);
}

static void test_default(void **st)
{
    struct conf c;
    (void)st;
    conf_default(&c);
    assert_int_equal(c.nlisten, 1);
    assert_string_equal(c.listen[0].host, "127.0.0.1");
    assert_string_equal(c.listen[0].port, "1502");
    assert_int_equal(c.nmodels, 1);
    assert_int_equal(c.model[0].unit, 1);
    assert_int_equal(c.model[0].preload, 1);
    assert_string_equal(c.state_dir, "./state");
}

static void test_full(void **st)
{
    struct conf c;
    char err[256];
    (void)st;
    assert_int_equal(load("[daemon]\nstate_dir=/var/lib/it2n\n"
                          "[modbus]\ntcp_listen = [::1]:1502\ntcp_listen = 0.0.0.0:502\n"
                          "float_word_order = dcba\ncoord_scale = 1000\n"
                          "[rtu:a]\ndevice=/dev/ttyUSB0\nparity=none\nbaud=9600\n"
                          "[model:7]\nunit_id=9\nn=2\nm=5\nchord=yes\nz=yes\n"
                          "[link:p]\ntype=usb\nusb=1d50:6018:ABC\n",
                          &c, err, sizeof err), 0);
    assert_int_equal(c.nlisten, 2);
    assert_string_equal(c.listen[0].host, "::1");
    assert_string_equal(c.listen[1].port, "502");
    assert_int_equal(c.word_order, 3);
    assert_int_equal(c.nrtu, 1);
    assert_int_equal(c.rtu[0].parity, 'N');
    assert_int_equal(c.nmodels, 1);
    assert_int_equal(c.model[0].id, 7);
    assert_int_equal(c.model[0].unit, 9);
    assert_int_equal(c.model[0].flags, IT2N_F_CHORD | IT2N_F_Z);
    /* The keys the file gives (a reload reconfigures a model holding data
     * only from those, never from a default). */
    assert_int_equal(c.model[0].set, CONF_SET_N | CONF_SET_M | CONF_SET_CHORD | CONF_SET_Z);
    assert_int_equal(c.link[0].vid, 0x1d50);
    assert_string_equal(c.link[0].serial, "ABC");
    assert_int_equal(load("[model:7]\nunit_id = 9\ntype1 = no\n", &c, err, sizeof err), 0);
    assert_int_equal(c.model[0].set, CONF_SET_TYPE1);
}

/* kind = bspline: grids up to 255 intervals; bezier (the default) keeps
 * its degrees 1..7 whatever the order of the keys. */
static void test_kind(void **st)
{
    struct conf c;
    char err[512];
    (void)st;
    assert_int_equal(load("[model:1]\nn = 255\nm = 64\nkind = bspline\nz = yes\n", &c, err, sizeof err), 0);
    assert_int_equal(c.nmodels, 1);
    assert_int_equal(c.model[0].kind, CONF_KIND_BSPLINE);
    assert_int_equal(c.model[0].n, 255);
    assert_int_equal(c.model[0].m, 64);
    assert_true(c.model[0].set & CONF_SET_KIND);
    assert_int_equal(load("[model:1]\nn = 7\n", &c, err, sizeof err), 0);
    assert_int_equal(c.model[0].kind, CONF_KIND_BEZIER);
    assert_false(c.model[0].set & CONF_SET_KIND);
}

static void test_errors(void **st)
{
    struct conf c, before;
    char err[256], want[256];
    (void)st;
    static const struct {
        const char *text;
        int line;
        const char *tail;
    } t[] = {
        { "[modbus]\ncoord_scale = 0\n", 2, "[modbus] coord_scale: expected 1..10000" },
        { "[daemon]\n\n; c\nnope = 1\n", 4, "[daemon] nope: unknown key in this section (it2nd --config-keys lists the keys)" },
        { "[model:1]\nn = 8\n", 2,
          "[model:1] n: 8 exceeds the bezier kind's degree limit 7; use 1..7, or kind = bspline for grids up to 255" },
        { "[model:1]\nkind = bezier\nm = 3\nm = 9\n", 4, "[model:1] m: duplicate key (first set on line 3)" },
        { "[model:1]\nm = 9\nkind = bezier\n", 2,
          "[model:1] m: 9 exceeds the bezier kind's degree limit 7; use 1..7, or kind = bspline for grids up to 255" },
        { "[model:1]\nkind = bspline\nn = 256\n", 3, "[model:1] n: expected 1..255 (bezier: 1..7)" },
        { "[model:1]\nkind = spline\n", 2, "[model:1] kind: expected bezier or bspline: did you mean 'bspline'?" },
        { "[model:1]\nn = 9\nchord = yes\nkind = bspline\n", 3,
          "[model:1] chord: the bspline kind has uniform parameters only: chord = yes needs kind = bezier" },
        { "[modbus]\nfloat_word_order = ABDC\n", 2, "[modbus] float_word_order: expected ABCD, CDAB, BADC or DCBA: did you mean 'ABCD'?" },
        { "[link:x]\nusb = zz\n", 2, "[link:x] usb: expected VID:PID[:serial] in hex" },
        { "[bogus]\na = 1\n", 2, "[bogus] a: unknown section (known: [daemon], [modbus], [listen:NAME], [rtu:NAME], "
          "[model:ID], [link:NAME], [sparkplug], [metrics])" },
        { "[modbus]\ntcp_listen = nocolon\n", 2, "[modbus] tcp_listen: expected host:port, [v6addr]:port or :port" },
        { "[daemon]\n\nuser = it2n-no-such-user\n", 3, "[daemon] user: unknown user 'it2n-no-such-user'" },
        { "[modbus]\ntcp_listen = 127.0.0.1:0\n", 2,
          "[modbus] tcp_listen: port 0: expected a port 1..65535 (0 would be a random port no client knows)" },
        { "[listen:a]\naddress = [::1]:0\n", 2,
          "[listen:a] address: port 0: expected a port 1..65535 (0 would be a random port no client knows)" },
        { "[modbus]\ncoord_scale = 100\nmax_clients = 4\ncoord_scale = 10\n", 4,
          "[modbus] coord_scale: duplicate key (first set on line 2)" },
        { "[model:1]\nunit_id = 1\n[daemon]\nfsync = no\n[model:1]\nn = 2\nunit_id = 2\n", 7,
          "[model:1] unit_id: duplicate key (first set on line 2)" },
        { "[listen:a]\naddress = 127.0.0.1:1502\nread_only = yes\nread_only = no\n", 4,
          "[listen:a] read_only: duplicate key (first set on line 3)" },
    };
    for (size_t k = 0; k < sizeof t / sizeof t[0]; k++) {
        conf_default(&before);
        assert_int_equal(load(t[k].text, &c, err, sizeof err), -1);
        snprintf(want, sizeof want, "%s:%d: %s", path, t[k].line, t[k].tail);
        assert_string_equal(err, want);
        assert_memory_equal(&c, &before, sizeof c); /* unchanged on error */
    }
    /* The first error is the one reported (libinih reads on after it). */
    assert_int_equal(load("[dAemon]\nstate_dir = /x\nfsync = yes\n", &c, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s:2: [dAemon] state_dir: unknown section: did you mean [daemon]?", path);
    assert_string_equal(err, want);
    /* A line longer than libinih's buffer is refused, not split (its tail
     * would be parsed as a setting), and the line number is the file's. */
    {
        char text[600];
        int n = snprintf(text, sizeof text, "[modbus]\n; ");
        memset(text + n, 'x', 300);
        snprintf(text + n + 300, sizeof text - (size_t)n - 300, "max_clients = 1\nidle_timeout = 5\n");
        assert_int_equal(load(text, &c, err, sizeof err), -1);
        snprintf(want, sizeof want, "%s:2: line too long (at most 198 characters)", path);
        assert_string_equal(err, want);
    }
    /* user resolved at load */
    assert_int_equal(load("[daemon]\nuser = root\n", &c, err, sizeof err), 0);
    assert_string_equal(c.user, "root");
    assert_int_equal(c.uid, 0);
    /* cross-key checks */
    assert_int_equal(load("[model:1]\nunit_id=3\n[model:2]\nunit_id=3\n", &c, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s:4: [model:2] unit_id: 3 already used by model 1", path);
    assert_string_equal(err, want);
    assert_int_equal(load("[model:1]\nn=2\npreload=paper\n", &c, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s:3: [model:1] preload: the paper data set needs n = m = 3, no z, not type1", path);
    assert_string_equal(err, want);
    assert_int_equal(load("[daemon]\nmax_models = 1\n[model:1]\nn=2\n[model:2]\nn=2\n", &c, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s:6: [daemon] max_models: 2 models configured, limit 1", path);
    assert_string_equal(err, want);
    assert_int_equal(load("[rtu:a]\nbaud = 9600\n", &c, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s:2: [rtu:a] baud: device is required in this section", path);
    assert_string_equal(err, want);
}

/* Repeatable keys still repeat; host names are resolved by
 * conf_check_hosts (not by conf_load), naming the address's line. */
static void test_repeat_and_hosts(void **st)
{
    struct conf c;
    char err[256], want[256];
    (void)st;
    assert_int_equal(load("[modbus]\ntcp_listen = 127.0.0.1:1502\ntcp_listen = [::1]:1502\n"
                          "[listen:a]\naddress = localhost:1503\nallow = 127.0.0.1\nallow = ::1\n",
                          &c, err, sizeof err), 0);
    assert_int_equal(c.nlisten, 3);
    assert_int_equal(c.listen[2].nallow, 2);
    assert_int_equal(conf_check_hosts(&c, path, err, sizeof err), 0);
    conf_default(&c);
    assert_int_equal(conf_check_hosts(&c, NULL, err, sizeof err), 0);
    /* .invalid never resolves (RFC 6761), with or without a resolver. */
    assert_int_equal(load("[modbus]\nmax_clients = 4\n\ntcp_listen = plc.invalid:1502\n", &c, err, sizeof err), 0);
    assert_int_equal(conf_check_hosts(&c, path, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s:4: [modbus] tcp_listen: cannot resolve host 'plc.invalid': ", path);
    assert_memory_equal(err, want, strlen(want));
    assert_int_equal(load("[listen:plc]\naddress = no-such-host.invalid:1502\n", &c, err, sizeof err), 0);
    assert_int_equal(conf_check_hosts(&c, path, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s:2: [listen:plc] address: cannot resolve host 'no-such-host.invalid': ", path);
    assert_memory_equal(err, want, strlen(want));
}

/* RS-485 options: defaults, both ways of switching the transceiver, and
 * the checks between them with the line of the key at fault. */
static void test_rs485(void **st)
{
    struct conf c, before;
    char err[320], want[320];
    (void)st;
    assert_int_equal(load("[rtu:a]\ndevice=/dev/ttyS1\n", &c, err, sizeof err), 0);
    assert_int_equal(c.rtu[0].rs485, 0);
    assert_int_equal(c.rtu[0].rts, CONF_RTS_NONE);
    assert_int_equal(c.rtu[0].rts_delay_us, -1);
    assert_int_equal(c.rtu[0].rts_on_send, -1);
    assert_int_equal(c.rtu[0].delay_before_ms, -1);
    assert_int_equal(c.rtu[0].delay_after_ms, -1);
    assert_int_equal(c.rtu[0].termination, -1);
    assert_int_equal(c.rtu[0].strict, 0);
    assert_int_equal(load("[rtu:k]\ndevice=/dev/ttyS1\nrs485=yes\nrs485_rts_on_send=low\n"
                          "rs485_delay_before_send_ms=0\nrs485_delay_after_send_ms=100\nrs485_termination=yes\n"
                          "rs485_strict=yes\n"
                          "[rtu:u]\ndevice=/dev/ttyUSB0\nrs485=yes\nrs485_rts=DOWN\nrs485_rts_delay_us=250\n",
                          &c, err, sizeof err), 0);
    assert_int_equal(c.nrtu, 2);
    assert_int_equal(c.rtu[0].rs485, 1);
    assert_int_equal(c.rtu[0].rts, CONF_RTS_NONE);
    assert_int_equal(c.rtu[0].rts_on_send, 0);
    assert_int_equal(c.rtu[0].delay_before_ms, 0);
    assert_int_equal(c.rtu[0].delay_after_ms, 100);
    assert_int_equal(c.rtu[0].termination, 1);
    assert_int_equal(c.rtu[0].strict, 1);
    assert_int_equal(c.rtu[1].rts, CONF_RTS_DOWN);
    assert_int_equal(c.rtu[1].rts_delay_us, 250);
    assert_int_equal(c.rtu[1].rts_on_send, -1);
    assert_int_equal(c.rtu[1].strict, 0);
    static const struct {
        const char *text;
        int line;
        const char *tail;
    } t[] = {
        /* bad values */
        { "[rtu:a]\ndevice=/d\nrs485=yes\nrs485_rts=high\n", 4, "[rtu:a] rs485_rts: expected none, up or down" },
        { "[rtu:a]\nrs485=yes\nrs485_rts=up\nrs485_rts_delay_us=100001\n", 4,
          "[rtu:a] rs485_rts_delay_us: expected microseconds 0..100000" },
        { "[rtu:a]\nrs485_rts_delay_us=-1\n", 2, "[rtu:a] rs485_rts_delay_us: expected microseconds 0..100000" },
        { "[rtu:a]\nrs485_delay_before_send_ms=101\n", 2,
          "[rtu:a] rs485_delay_before_send_ms: expected milliseconds 0..100 (the kernel's limit)" },
        { "[rtu:a]\nrs485_delay_after_send_ms=x\n", 2,
          "[rtu:a] rs485_delay_after_send_ms: expected milliseconds 0..100 (the kernel's limit)" },
        { "[rtu:a]\nrs485_rts_on_send=yes\n", 2, "[rtu:a] rs485_rts_on_send: expected high or low" },
        { "[rtu:a]\nrs485_termination=2\n", 2, "[rtu:a] rs485_termination: expected yes or no" },
        { "[rtu:a]\nrs485_strict=maybe\n", 2, "[rtu:a] rs485_strict: expected yes or no" },
        { "[rtu:a]\nrs485_foo=1\n", 2, "[rtu:a] rs485_foo: unknown key in this section (it2nd --config-keys lists the keys)" },
        /* options without rs485 = yes: the first option's line */
        { "[rtu:a]\ndevice=/d\n\nrs485_rts=up\nrs485_rts_delay_us=10\n", 4,
          "[rtu:a] rs485_rts: needs rs485 = yes in this section" },
        { "[rtu:a]\ndevice=/d\nrs485_strict=yes\n", 3, "[rtu:a] rs485_strict: needs rs485 = yes in this section" },
        /* rs485 turned off again later: a duplicate key, refused as such. */
        { "[rtu:a]\ndevice=/d\nrs485=yes\nrs485_delay_after_send_ms=1\nrs485=no\n", 5,
          "[rtu:a] rs485: duplicate key (first set on line 3)" },
        /* an RTS delay without libmodbus switching RTS */
        { "[rtu:a]\ndevice=/d\nrs485=yes\nrs485_rts_delay_us=10\n", 4,
          "[rtu:a] rs485_rts_delay_us: needs rs485_rts = up or down (libmodbus switching RTS)" },
        { "[rtu:a]\ndevice=/d\nrs485=yes\nrs485_rts=none\nrs485_rts_delay_us=10\n", 5,
          "[rtu:a] rs485_rts_delay_us: needs rs485_rts = up or down (libmodbus switching RTS)" },
        /* kernel options and libmodbus RTS are exclusive */
        { "[rtu:a]\ndevice=/d\nrs485=yes\nrs485_rts=up\nrs485_strict=yes\nrs485_delay_before_send_ms=5\n", 6,
          "[rtu:a] rs485_delay_before_send_ms: a kernel RS-485 option, but rs485_rts = up (line 4) has libmodbus "
          "switch RTS instead; use one or the other" },
        { "[rtu:a]\ndevice=/d\nrs485=yes\nrs485_termination=no\nrs485_rts=down\n", 4,
          "[rtu:a] rs485_termination: a kernel RS-485 option, but rs485_rts = down (line 5) has libmodbus "
          "switch RTS instead; use one or the other" },
    };
    for (size_t k = 0; k < sizeof t / sizeof t[0]; k++) {
        conf_default(&before);
        assert_int_equal(load(t[k].text, &c, err, sizeof err), -1);
        snprintf(want, sizeof want, "%s:%d: %s", path, t[k].line, t[k].tail);
        assert_string_equal(err, want);
        assert_memory_equal(&c, &before, sizeof c); /* unchanged on error */
    }
}

/* A configuration that cannot be read is an error, never an empty file
 * (issue 8: "-c DIR" passed --check-config and a reload replaced the
 * running models with the built-in default); an empty section is an error
 * with its header's line (an empty [model:5] was ignored: unit 5 answered
 * nothing while the default model was served). Nothing changes on error. */
#define NAME40 "abcdefghijklmnopqrstuvwxyz0123456789ABCD"
static void test_unreadable_and_empty(void **st)
{
    struct conf c, before;
    char err[512], want[512], dir[64];
    (void)st;
    snprintf(dir, sizeof dir, "/tmp/it2nd-test-conf-dir.%d", (int)getpid());
    assert_int_equal(mkdir(dir, 0700), 0);
    conf_default(&c);
    before = c;
    assert_int_equal(conf_load(&c, dir, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s: a directory, not a regular file: the configuration must be a regular file "
             "(nothing was read)", dir);
    assert_string_equal(err, want);
    assert_memory_equal(&c, &before, sizeof c);
    assert_int_equal(rmdir(dir), 0);
    assert_int_equal(conf_load(&c, dir, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s: cannot open: No such file or directory", dir);
    assert_string_equal(err, want);
    assert_memory_equal(&c, &before, sizeof c);

    static const struct {
        const char *text;
        int line;
        const char *tail;
    } t[] = {
        { "[model:5]\n", 1, "[model:5]: empty section: its required keys are missing (a model needs at least one of "
                             "unit_id, kind, n, m, z, type1, chord, preload; without any the section would be ignored)" },
        { "[daemon]\nfsync = no\n\n[rtu:a]\n; device = /dev/ttyS0\n[model:2]\nn = 2\n", 4,
          "[rtu:a]: empty section: its required keys are missing (device is required)" },
        { "[model:1]\nn = 2\n[link:x]\n", 3,
          "[link:x]: empty section: its required keys are missing (type and device (serial) or usb (usb) are required)" },
        { "[daemon]\n[modbus]\nmax_clients = 4\n", 1,
          "[daemon]: empty section: its required keys are missing (a section with no keys has no effect; remove it "
          "or add keys)" },
        /* the header's name in full, however long (make fuzz: it was cut
         * at 63 bytes and quoted as if whole) */
        { "[model:1]\nn = 2\n[rtu:" NAME40 NAME40 NAME40 "]\n", 3,
          "[rtu:" NAME40 NAME40 NAME40 "]: empty section: its required keys are missing (device is required)" },
        /* the first error in the file wins */
        { "[modbus]\nmax_clients = 0\n[model:5]\n", 2, "[modbus] max_clients: expected 1..512" },
        { "[model:5]\n[modbus]\nmax_clients = 0\n", 1, "[model:5]: empty section: its required keys are missing (a "
          "model needs at least one of unit_id, kind, n, m, z, type1, chord, preload; without any the section would be "
          "ignored)" },
    };
    for (size_t k = 0; k < sizeof t / sizeof t[0]; k++) {
        conf_default(&before);
        assert_int_equal(load(t[k].text, &c, err, sizeof err), -1);
        snprintf(want, sizeof want, "%s:%d: %s", path, t[k].line, t[k].tail);
        assert_string_equal(err, want);
        assert_memory_equal(&c, &before, sizeof c);
    }
    /* A section given twice with keys in the first is fine only if the
     * second has keys too; [model:5] with one key is a model on unit 5. */
    assert_int_equal(load("[model:5]\nn = 3\n", &c, err, sizeof err), 0);
    assert_int_equal(c.nmodels, 1);
    assert_int_equal(c.model[0].unit, 5);
}

/* What a non-atomic rewrite leaves (issue 20 item 2): an empty file, a
 * file cut mid-line, one with only comments, a FIFO with no writer and
 * /dev/zero are errors, never a configuration (an empty file loaded as the
 * built-in default and a reload then discarded the running models; a FIFO
 * or /dev/zero hung --check-config). Nothing blocks, nothing changes. */
static void test_partial_files(void **st)
{
    struct conf c, before;
    char err[512], want[512], fifo[64];
    (void)st;
    static const struct {
        const char *text;
        int line;               /* 0: no line in the message */
        const char *tail;
    } t[] = {
        { "", 0, "empty file (0 bytes): refused, a configuration sets at least one key (for the built-in default "
                 "run it2nd without -c)" },
        { "[model:1]\nn = 3", 2, "no newline at the end of the last line: the file looks cut short (an unfinished "
                                 "or interrupted rewrite); if it is complete, end it with a newline" },
        { "[model:5]\nunit_id = 5\nn = 3\n[mod", 4, "no newline at the end of the last line: the file looks cut "
          "short (an unfinished or interrupted rewrite); if it is complete, end it with a newline" },
        { "\n", 1, "no key in the file (only blank lines and comments): refused, a configuration sets at least one "
                   "key (for the built-in default run it2nd without -c)" },
        { "; it2nd.conf\n\n# nothing yet\n", 1, "no key in the file (only blank lines and comments): refused, a "
          "configuration sets at least one key (for the built-in default run it2nd without -c)" },
    };
    for (size_t k = 0; k < sizeof t / sizeof t[0]; k++) {
        conf_default(&before);
        assert_int_equal(load(t[k].text, &c, err, sizeof err), -1);
        if (t[k].line)
            snprintf(want, sizeof want, "%s:%d: %s", path, t[k].line, t[k].tail);
        else
            snprintf(want, sizeof want, "%s: %s", path, t[k].tail);
        assert_string_equal(err, want);
        assert_memory_equal(&c, &before, sizeof c);
    }
    /* Blocks allocated but never written before a crash read as zeros. */
    static const char zeros[] = "[model:1]\nn = 3\n\0\0\0\n";
    assert_int_equal(load_n(zeros, sizeof zeros - 1, &c, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s:3: NUL byte in the line (at most 198 characters)", path);
    assert_string_equal(err, want);
    /* The same text with its newline is a configuration. */
    assert_int_equal(load("[model:1]\nn = 3\n", &c, err, sizeof err), 0);
    assert_int_equal(c.model[0].n, 3);
    /* Non-regular files: refused before any read (a FIFO without a writer
     * would block a blocking open, /dev/zero a read forever). */
    snprintf(fifo, sizeof fifo, "/tmp/it2nd-test-conf-fifo.%d", (int)getpid());
    assert_int_equal(mkfifo(fifo, 0600), 0);
    conf_default(&c);
    before = c;
    assert_int_equal(conf_load(&c, fifo, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s: a FIFO, not a regular file: the configuration must be a regular file (nothing "
             "was read)", fifo);
    assert_string_equal(err, want);
    assert_int_equal(unlink(fifo), 0);
    assert_int_equal(conf_load(&c, "/dev/zero", err, sizeof err), -1);
    assert_string_equal(err, "/dev/zero: a character device, not a regular file: the configuration must be a regular "
                             "file (nothing was read)");
    assert_memory_equal(&c, &before, sizeof c);
    /* Over the size bound: refused without reading it. */
    {
        FILE *f = fopen(path, "w");
        assert_non_null(f);
        assert_int_equal(fseek(f, CONF_MAX_BYTES, SEEK_SET), 0);
        fputs("\n", f);
        fclose(f);
        assert_int_equal(conf_load(&c, path, err, sizeof err), -1);
        snprintf(want, sizeof want, "%s: %d bytes: larger than a configuration can be (%d bytes at most)", path,
                 CONF_MAX_BYTES + 1, CONF_MAX_BYTES);
        assert_string_equal(err, want);
        unlink(path);
    }
}

/* [model:ID] removed = yes: the id leaves the model list for conf.removed
 * (its unit id is free, max_models does not count it); every model removed
 * is an error. */
static void test_removed(void **st)
{
    struct conf c;
    char err[512], want[512];
    (void)st;
    assert_int_equal(load("[daemon]\nmax_models = 1\n[model:5]\nunit_id = 5\nremoved = yes\n"
                          "[model:6]\nunit_id = 5\n", &c, err, sizeof err), 0);
    assert_int_equal(c.nmodels, 1);
    assert_int_equal(c.model[0].id, 6);
    assert_int_equal(c.model[0].unit, 5);
    assert_int_equal(c.nremoved, 1);
    assert_int_equal(c.removed[0], 5);
    assert_true(conf_removes(&c, 5));
    assert_false(conf_removes(&c, 6));
    assert_int_equal(load("[model:5]\nremoved = no\n", &c, err, sizeof err), 0);
    assert_int_equal(c.nmodels, 1);
    assert_int_equal(c.nremoved, 0);
    assert_int_equal(load("[model:5]\nremoved = yes\n[model:0]\nremoved = yes\n", &c, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s:4: [model:0] removed: every [model:] section says removed = yes: at least one "
             "model must be served", path);
    assert_string_equal(err, want);
    assert_int_equal(load("[model:5]\nremoved = maybe\n", &c, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s:2: [model:5] removed: expected yes or no", path);
    assert_string_equal(err, want);
    /* default_model may not name a removed model */
    assert_int_equal(load("[modbus]\ndefault_model = 5\n[model:5]\nremoved = yes\n[model:6]\nn = 2\n", &c, err,
                          sizeof err), -1);
    snprintf(want, sizeof want, "%s:2: [modbus] default_model: no [model:5] is configured", path);
    assert_string_equal(err, want);
}

/* Two sections on one device (issue 20 item 6): the same path is refused
 * by conf_load; the same device through a symlink (or another node of the
 * same character device) by conf_check_devices, naming both sections. */
static void test_device_conflicts(void **st)
{
    struct conf c;
    char err[512], want[512], text[512], lnk[64];
    (void)st;
    assert_int_equal(load("[rtu:a]\ndevice = /dev/ttyS1\n[link:b]\ntype = serial\n\ndevice = /dev/ttyS1\n", &c,
                          err, sizeof err), -1);
    snprintf(want, sizeof want, "%s:6: [link:b] device: /dev/ttyS1 is also the device of [rtu:a] (line 2): one "
             "device serves one section (the other would find it locked by another process)", path);
    assert_string_equal(err, want);
    assert_int_equal(load("[link:x]\ndevice = /dev/ttyACM0\n[rtu:a]\ndevice = /dev/ttyS1\n[rtu:b]\n"
                          "device = /dev/ttyS1\n[link:y]\ndevice = /dev/ttyACM0\n", &c, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s:6: [rtu:b] device: /dev/ttyS1 is also the device of [rtu:a] (line 4): one "
             "device serves one section (the other would find it locked by another process)", path);
    assert_string_equal(err, want);
    assert_int_equal(load("[link:x]\ndevice = /dev/ttyACM0\n[link:y]\ndevice = /dev/ttyACM0\n", &c, err,
                          sizeof err), -1);
    /* A USB link has no device path: no conflict with an RTU port. */
    assert_int_equal(load("[rtu:a]\ndevice = /dev/ttyS1\n[link:u]\ntype = usb\nusb = 1d50:6018\n", &c, err,
                          sizeof err), 0);
    assert_int_equal(conf_check_devices(&c, path, err, sizeof err), 0);
    /* Through a symlink: passes conf_load, refused by conf_check_devices. */
    snprintf(lnk, sizeof lnk, "/tmp/it2nd-test-conf-tty.%d", (int)getpid());
    unlink(lnk);
    assert_int_equal(symlink("/dev/null", lnk), 0);
    snprintf(text, sizeof text, "[rtu:bus]\ndevice = /dev/null\n[link:inst]\ntype = serial\ndevice = %s\n", lnk);
    assert_int_equal(load(text, &c, err, sizeof err), 0);
    assert_int_equal(conf_check_devices(&c, path, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s:5: [link:inst] device: %s is the same device as /dev/null of [rtu:bus] (line 2), "
             "both /dev/null: one device serves one section (the other would find it locked by another process)",
             path, lnk);
    assert_string_equal(err, want);
    /* Two different devices, and a path that does not exist yet: fine. */
    snprintf(text, sizeof text, "[rtu:bus]\ndevice = /dev/zero\n[link:inst]\ndevice = %s\n[link:later]\n"
             "device = /dev/it2n-no-such-tty\n", lnk);
    assert_int_equal(load(text, &c, err, sizeof err), 0);
    assert_int_equal(conf_check_devices(&c, path, err, sizeof err), 0);
    assert_int_equal(unlink(lnk), 0);
}

static int allowed6(const struct conf_listen *l, const char *a)
{
    struct sockaddr_in6 sa;
    memset(&sa, 0, sizeof sa);
    sa.sin6_family = AF_INET6;
    assert_int_equal(inet_pton(AF_INET6, a, &sa.sin6_addr), 1);
    return acl_allowed(l, (const struct sockaddr *)&sa);
}

static int allowed4(const struct conf_listen *l, const char *a)
{
    struct sockaddr_in sa;
    memset(&sa, 0, sizeof sa);
    sa.sin_family = AF_INET;
    assert_int_equal(inet_pton(AF_INET, a, &sa.sin_addr), 1);
    return acl_allowed(l, (const struct sockaddr *)&sa);
}

/* [listen:NAME] sections, allow-lists (IPv4, IPv6, prefixes not on a byte
 * boundary, IPv4-mapped IPv6 clients of a dual-stack listener), defaults
 * of the slot keys, write_protect. */
static void test_listen_acl(void **st)
{
    struct conf c;
    char err[256];
    (void)st;
    conf_default(&c);
    assert_int_equal(c.tcp_keepalive, 60);
    assert_int_equal(c.evict_idle, 500);
    assert_int_equal(c.max_pending, 1024);
    assert_int_equal(load("[modbus]\nmax_pending = 16\n", &c, err, sizeof err), 0);
    assert_int_equal(c.max_pending, 16);
    assert_int_equal(load("[modbus]\nmax_pending = 15\n", &c, err, sizeof err), -1);
    assert_non_null(strstr(err, ":2: [modbus] max_pending: expected 16..65536"));
    assert_int_equal(load("[listen:plc]\naddress = :502\nallow = 10.1.0.0/16, 192.168.7.128/25\nallow = fd00::/8\n"
                          "read_only = yes\n[listen:eng]\naddress = [::1]:1502\nallow = ::1\n"
                          "[modbus]\ntcp_listen = 127.0.0.1:1503\n[model:2]\nwrite_protect = yes\n",
                          &c, err, sizeof err), 0);
    assert_int_equal(c.nlisten, 3);
    const struct conf_listen *plc = &c.listen[0], *eng = &c.listen[1], *plain = &c.listen[2];
    assert_string_equal(plc->name, "plc");
    assert_string_equal(plc->host, "");
    assert_string_equal(plc->port, "502");
    assert_int_equal(plc->read_only, 1);
    assert_int_equal(plc->nallow, 3);
    assert_string_equal(eng->host, "::1");
    assert_int_equal(eng->read_only, 0);
    assert_string_equal(plain->name, "");
    assert_int_equal(plain->nallow, 0);
    assert_int_equal(c.model[0].write_protect, 1);

    assert_true(allowed4(plc, "10.1.255.3"));
    assert_false(allowed4(plc, "10.2.0.1"));
    assert_true(allowed4(plc, "192.168.7.200"));
    assert_false(allowed4(plc, "192.168.7.127"));
    assert_true(allowed6(plc, "::ffff:10.1.2.3"));    /* IPv4 client of a dual-stack socket */
    assert_false(allowed6(plc, "::ffff:10.3.2.3"));
    assert_true(allowed6(plc, "fd12:3456::1"));
    assert_false(allowed6(plc, "fe80::1"));
    assert_false(allowed6(plc, "::a01:203"));         /* IPv4-compatible is not IPv4 */
    assert_true(allowed6(eng, "::1"));
    assert_false(allowed6(eng, "::2"));
    assert_false(allowed4(eng, "127.0.0.1"));
    assert_true(allowed4(plain, "203.0.113.9"));    /* no allow entries: everyone */
    assert_true(allowed6(plain, "2001:db8::1"));

    struct acl_prefix p;
    char why[160];
    assert_int_equal(acl_parse_prefix("0.0.0.0/0", &p, why, sizeof why), 0);
    assert_int_equal(acl_parse_prefix("[2001:db8::]/32", &p, why, sizeof why), 0);
    assert_int_equal(p.family, 6);
    assert_int_equal(p.bits, 32);
    assert_int_equal(acl_parse_prefix("10.0.0.1/31", &p, why, sizeof why), -1);
    assert_int_equal(acl_parse_prefix("2001:db8::/129", &p, why, sizeof why), -1);
    assert_int_equal(acl_parse_prefix("10.0.0.0/", &p, why, sizeof why), -1);
    assert_int_equal(acl_parse_prefix("10.0.0.0/8x", &p, why, sizeof why), -1);
    assert_int_equal(acl_parse_prefix("", &p, why, sizeof why), -1);
}

/* Issue 18 item 4: a misspelt key or section names the nearest known one;
 * a key of another section says which; a line without '=' is named as
 * such (not "syntax error", not an empty section). */
static void test_suggestions(void **st)
{
    struct conf c, before;
    char err[320], want[320];
    (void)st;
    static const struct {
        const char *text;
        int line;
        const char *tail;
    } t[] = {
        { "[daemon]\nfsync = yes\nstat_dir = ./x\n", 3, "[daemon] stat_dir: unknown key: did you mean 'state_dir'?" },
        { "[daemon]\nsnapshot_intervall = 5\n", 2,
          "[daemon] snapshot_intervall: unknown key: did you mean 'snapshot_interval'?" },
        { "[modbus]\nmax_client = 3\n", 2, "[modbus] max_client: unknown key: did you mean 'max_clients'?" },
        { "[modbus]\nFloat_Word_Order = ABCD\n", 2,
          "[modbus] Float_Word_Order: unknown key: did you mean 'float_word_order'?" },
        { "[model:1]\nunitid = 3\n", 2, "[model:1] unitid: unknown key: did you mean 'unit_id'?" },
        { "[model:1]\ntpye1 = yes\n", 2, "[model:1] tpye1: unknown key: did you mean 'type1'?" },
        { "[link:a]\nbuad = 9600\n", 2, "[link:a] buad: unknown key: did you mean 'baud'?" },
        { "[metrics]\nlisen = :9102\n", 2, "[metrics] lisen: unknown key: did you mean 'listen'?" },
        { "[modbus]\nstate_dir = x\n", 2, "[modbus] state_dir: unknown key: 'state_dir' is a key of [daemon]" },
        { "[daemon]\ntcp_listen = :1502\n", 2, "[daemon] tcp_listen: unknown key: 'tcp_listen' is a key of [modbus]" },
        { "[model:1]\nx = 1\n", 2, "[model:1] x: unknown key in this section (it2nd --config-keys lists the keys)" },
        /* keys the hand-kept suggestion list before the schema missed */
        { "[modbus]\nmax_pendng = 20\n", 2, "[modbus] max_pendng: unknown key: did you mean 'max_pending'?" },
        { "[model:1]\nkidn = bspline\n", 2, "[model:1] kidn: unknown key: did you mean 'kind'?" },
        { "[sparkplg]\nbroker = x\n", 2, "[sparkplg] broker: unknown section: did you mean [sparkplug]?" },
        { "[rtus:a]\nbaud = 9600\n", 2, "[rtus:a] baud: unknown section: did you mean [rtu:a]?" },
        { "[sparkplug]\nbroker = x\ngroup_id = g\nedge_node_id = e\nkeepalive = 3\n", 5,
          "[sparkplug] keepalive: expected seconds 5..3600" },
        { "[sparkplug]\nkeepalve = 30\n", 2, "[sparkplug] keepalve: unknown key: did you mean 'keepalive'?" },
        { "[model:1]\nlisten = :9102\n", 2, "[model:1] listen: unknown key: 'listen' is a key of [metrics]" },
        { "[rtu:a]\ngroup_id = g\n", 2, "[rtu:a] group_id: unknown key: 'group_id' is a key of [sparkplug]" },
        /* enum values: the nearest listed one */
        { "[rtu:a]\ndevice = /dev/null\nparity = evn\n", 3, "[rtu:a] parity: expected none, even or odd: did you mean 'even'?" },
        { "[modbus]\nfloat_word_order = CDBA\n", 2,
          "[modbus] float_word_order: expected ABCD, CDAB, BADC or DCBA: did you mean 'CDAB'?" },
        { "[modbus]\ndefault_model = atuo\n", 2,
          "[modbus] default_model: expected auto, none or a model id 0..254: did you mean 'auto'?" },
        { "[link:a]\ntype = serail\n", 2, "[link:a] type: expected serial or usb: did you mean 'serial'?" },
        { "[model:1]\npreload = none\nkind = zzz\n", 3, "[model:1] kind: expected bezier or bspline" },
        { "[modbsu]\nx = 1\n", 2, "[modbsu] x: unknown section: did you mean [modbus]?" },
        { "[models:2]\nn = 2\n", 2, "[models:2] n: unknown section: did you mean [model:2]?" },
        { "[metric]\nlisten = :9102\n", 2, "[metric] listen: unknown section: did you mean [metrics]?" },
        /* no '=': named, with the key when the first word is one */
        { "[daemon]\nstate_dir ./x\n", 2,
          "[daemon] 'state_dir ./x': no '=' in this line: expected key = value (state_dir = ...?)" },
        { "[modbus]\nmax_clients = 4\n\ncoord_scale 100\n", 4,
          "[modbus] 'coord_scale 100': no '=' in this line: expected key = value (coord_scale = ...?)" },
        { "[daemon]\nfsync = yes\nhello world\n", 3, "[daemon] 'hello world': no '=' in this line: expected key = value" },
        { "oops\n[daemon]\nfsync = yes\n", 1, "[(no section)] 'oops': no '=' in this line: expected key = value" },
    };
    for (size_t k = 0; k < sizeof t / sizeof t[0]; k++) {
        conf_default(&before);
        assert_int_equal(load(t[k].text, &c, err, sizeof err), -1);
        snprintf(want, sizeof want, "%s:%d: %s", path, t[k].line, t[k].tail);
        assert_string_equal(err, want);
        assert_memory_equal(&c, &before, sizeof c);
    }
    /* Every key of the schema is a key of the parser (a nonsense value is
     * refused for its value, never as unknown). */
    {
        int ns;
        const struct conf_section *sec = conf_schema_sections(&ns);
        for (int k = 0; k < ns; k++)
            for (int j = 0; j < sec[k].nkeys; j++) {
                char text[160];
                snprintf(text, sizeof text, "[%s%s]\n%s = \x01nonsense\n", sec[k].name, sec[k].arg ? "1" : "",
                         sec[k].keys[j].name);
                err[0] = 0; /* username takes any text */
                load(text, &c, err, sizeof err);
                if (strstr(err, "unknown key") || strstr(err, "unknown section"))
                    fail_msg("%s", err);
            }
    }
    assert_null(conf_schema_section("bogus"));
    assert_null(conf_schema_section("rtu:"));  /* a named kind needs its name */
}

/* [metrics] listen: off by default, parsed like a listener, not on a
 * Modbus listener's address. */
static void test_metrics_section(void **st)
{
    struct conf c;
    char err[320], want[320];
    (void)st;
    conf_default(&c);
    assert_string_equal(c.metrics.port, "");
    assert_int_equal(load("[metrics]\nlisten = 127.0.0.1:9102\n", &c, err, sizeof err), 0);
    assert_string_equal(c.metrics.host, "127.0.0.1");
    assert_string_equal(c.metrics.port, "9102");
    assert_int_equal(c.metrics.line, 2);
    assert_int_equal(load("[metrics]\nlisten = [::1]:9102\n", &c, err, sizeof err), 0);
    assert_string_equal(c.metrics.host, "::1");
    assert_int_equal(load("[metrics]\nlisten = none\n", &c, err, sizeof err), 0);
    assert_string_equal(c.metrics.port, "");
    assert_int_equal(load("[metrics]\nlisten = 9102\n", &c, err, sizeof err), -1);
    snprintf(want, sizeof want, "%s:2: [metrics] listen: expected host:port, [v6addr]:port, :port or none", path);
    assert_string_equal(err, want);
    assert_int_equal(load("[metrics]\nlisten = :0\n", &c, err, sizeof err), -1);
    assert_non_null(strstr(err, "port 0"));
    assert_int_equal(load("[modbus]\ntcp_listen = 127.0.0.1:1600\n[metrics]\nlisten = 127.0.0.1:1600\n", &c, err,
                          sizeof err), -1);
    snprintf(want, sizeof want, "%s:4: [metrics] listen: 127.0.0.1:1600 is also a Modbus listener address (line 2): "
             "the metrics endpoint needs a port of its own", path);
    assert_string_equal(err, want);
    assert_int_equal(load("[metrics]\nlisten = 127.0.0.1:1502\n", &c, err, sizeof err), -1);
    assert_non_null(strstr(err, "(the built-in default)"));
}

/* it2nd --listen / --state-dir / --metrics over the defaults or a file. */
/* A reload reopens a port or link, or logs a [sparkplug] change, only when
 * the section says something else: not when lines above moved it or its
 * keys were reordered (the line fields are where, not what). */
static void test_same_sections(void **st)
{
    static struct conf a, b;
    char err[256];
    const char *text = "[rtu:bus]\ndevice = /dev/it2n-test-rtu\nbaud = 19200\n"
                       "[link:inst]\ntype = serial\ndevice = /dev/it2n-test-link\n"
                       "[sparkplug]\nbroker = 127.0.0.1\ngroup_id = g\nedge_node_id = e\n";
    char moved[512];
    (void)st;
    assert_int_equal(load(text, &a, err, sizeof err), 0);
    snprintf(moved, sizeof moved, "# a comment\n\n%s", text);
    assert_int_equal(load(moved, &b, err, sizeof err), 0);
    assert_int_not_equal(a.rtu[0].device_line, b.rtu[0].device_line);
    assert_true(conf_rtu_same(&a.rtu[0], &b.rtu[0]));
    assert_true(conf_link_same(&a.link[0], &b.link[0]));
    assert_true(spb_conf_same(&a.spb, &b.spb));
    assert_int_equal(load("[rtu:bus]\ndevice = /dev/it2n-test-rtu\nbaud = 38400\n"
                          "[link:inst]\ntype = serial\ndevice = /dev/it2n-test-link\nbaud = 57600\n"
                          "[sparkplug]\nedge_node_id = e\ngroup_id = g\nbroker = 127.0.0.1\nkeepalive = 60\n",
                          &b, err, sizeof err), 0);
    assert_false(conf_rtu_same(&a.rtu[0], &b.rtu[0]));
    assert_false(conf_link_same(&a.link[0], &b.link[0]));
    assert_false(spb_conf_same(&a.spb, &b.spb));
    b.spb.keepalive = a.spb.keepalive; /* keys in another order, else the same */
    assert_true(spb_conf_same(&a.spb, &b.spb));
}

static void test_override(void **st)
{
    struct conf c, before;
    char err[320];
    struct conf_override o;
    (void)st;
    memset(&o, 0, sizeof o);
    conf_default(&c);
    o.listen[0] = "127.0.0.1:15020";
    o.listen[1] = "[::1]:15020";
    o.nlisten = 2;
    o.state_dir = "./state2";
    o.metrics = "127.0.0.1:9102";
    assert_int_equal(conf_apply_override(&c, &o, err, sizeof err), 0);
    assert_int_equal(c.nlisten, 2);
    assert_string_equal(c.listen[0].host, "127.0.0.1");
    assert_string_equal(c.listen[0].port, "15020");
    assert_string_equal(c.listen[1].host, "::1");
    assert_string_equal(c.state_dir, "./state2");
    assert_string_equal(c.metrics.port, "9102");
    /* over a file: the file's listeners ([listen:NAME] too) are replaced,
     * everything else kept */
    assert_int_equal(load("[daemon]\nstate_dir = /var/x\nfsync = no\n[listen:a]\naddress = 0.0.0.0:502\n"
                          "allow = 10.0.0.0/8\n[metrics]\nlisten = :9102\n", &c, err, sizeof err), 0);
    memset(&o, 0, sizeof o);
    o.listen[0] = ":15020";
    o.nlisten = 1;
    o.metrics = "none";
    assert_int_equal(conf_apply_override(&c, &o, err, sizeof err), 0);
    assert_int_equal(c.nlisten, 1);
    assert_string_equal(c.listen[0].host, "");
    assert_int_equal(c.listen[0].nallow, 0);
    assert_string_equal(c.state_dir, "/var/x");
    assert_int_equal(c.fsync, 0);
    assert_string_equal(c.metrics.port, "");
    /* errors: nothing changed */
    static const struct {
        const char *listen, *state_dir, *metrics, *msg;
    } t[] = {
        { "127.0.0.1", NULL, NULL, "--listen '127.0.0.1': expected HOST:PORT, [V6ADDR]:PORT or :PORT" },
        { "127.0.0.1:0", NULL, NULL, "--listen '127.0.0.1:0': port 0: expected a port 1..65535" },
        { "127.0.0.1:99999", NULL, NULL, "--listen '127.0.0.1:99999': expected HOST:PORT, [V6ADDR]:PORT or :PORT" },
        { NULL, "", NULL, "--state-dir '': path empty or longer than 255 bytes" },
        { NULL, NULL, "9102", "--metrics '9102': expected HOST:PORT, [V6ADDR]:PORT, :PORT or none" },
        { "127.0.0.1:9102", NULL, "127.0.0.1:9102", "127.0.0.1:9102: the metrics endpoint and a Modbus listener on one "
          "address; give --metrics (or [metrics] listen) a port of its own" },
    };
    for (size_t k = 0; k < sizeof t / sizeof t[0]; k++) {
        conf_default(&c);
        before = c;
        memset(&o, 0, sizeof o);
        if (t[k].listen) {
            o.listen[0] = t[k].listen;
            o.nlisten = 1;
        }
        o.state_dir = t[k].state_dir;
        o.metrics = t[k].metrics;
        assert_int_equal(conf_apply_override(&c, &o, err, sizeof err), -1);
        assert_string_equal(err, t[k].msg);
        assert_memory_equal(&c, &before, sizeof c);
    }
    conf_default(&c);
    memset(&o, 0, sizeof o);
    o.listen[0] = o.listen[1] = "127.0.0.1:15020";
    o.nlisten = 2;
    assert_int_equal(conf_apply_override(&c, &o, err, sizeof err), -1);
    assert_string_equal(err, "--listen '127.0.0.1:15020': given twice");
}

/* ---- the schema (daemon/conf_schema.c) ---- */

/* The struct a section's keys are stored in, in a conf loaded from one
 * section of that kind. */
static void *section_base(struct conf *c, const struct conf_section *s)
{
    switch (s->id) {
    case CONF_SEC_LISTEN: return &c->listen[0];
    case CONF_SEC_RTU: return &c->rtu[0];
    case CONF_SEC_MODEL: return &c->model[0];
    case CONF_SEC_LINK: return &c->link[0];
    case CONF_SEC_SPARKPLUG: return &c->spb;
    case CONF_SEC_METRICS: return &c->metrics;
    default: return c;
    }
}

/* A file of one section s: `before` (what the section needs besides k),
 * then "k = value", then `after` (other sections). */
static int load_key(const struct conf_section *s, const struct conf_key *k, const char *value, struct conf *c,
                    char *err, size_t size)
{
    char text[512], after[64] = "";
    const char *before = "";
    switch (s->id) {
    case CONF_SEC_LISTEN: before = "address = 127.0.0.1:1600\n"; break;
    case CONF_SEC_RTU:
        before = k->flags & CONF_K_LIBMODBUS ? "device = /dev/null\nrs485 = yes\nrs485_rts = up\n" :
                 k->flags & CONF_K_RS485 ? "device = /dev/null\nrs485 = yes\n" : "device = /dev/null\n";
        break;
    case CONF_SEC_LINK: before = "device = /dev/null\nusb = 1234:5678\n"; break;
    case CONF_SEC_SPARKPLUG: /* the required keys, but k */
        before = !strcmp(k->name, "broker") ? "group_id = g\nedge_node_id = e\n" :
                 !strcmp(k->name, "group_id") ? "broker = localhost\nedge_node_id = e\n" :
                 !strcmp(k->name, "edge_node_id") ? "broker = localhost\ngroup_id = g\n" :
                 "broker = localhost\ngroup_id = g\nedge_node_id = e\n";
        break;
    case CONF_SEC_MODEL: before = "kind = bspline\n"; break;
    default: break;
    }
    if (!strcmp(k->name, "default_model")) /* names a configured model */
        snprintf(after, sizeof after, "[model:%s]\nunit_id = 9\n", value);
    if (s->id == CONF_SEC_MODEL && !strcmp(k->name, "kind"))
        before = "";
    snprintf(text, sizeof text, "[%s%s]\n%s%s = %s\n%s", s->name, s->arg ? (s->id == CONF_SEC_MODEL ? "1" : "a") : "",
             before, k->name, value, after);
    return load(text, c, err, size);
}

/* The line of k in load_key's file. */
static int key_line_in(const char *text_before)
{
    int n = 2;
    for (const char *c = text_before; *c; c++)
        n += *c == '\n';
    return n;
}

static long stored(const void *base, const struct conf_key *k)
{
    const char *at = (const char *)base + k->off;
    if (k->type == CONF_T_FLAG)
        return (*(const unsigned *)(const void *)at & k->bit) != 0;
    return k->size == 1 ? (long)*at : (long)*(const int *)(const void *)at;
}

/* Every INT key: both ends of its range are taken and stored where the
 * schema says; one past either end is refused naming the range. */
static void test_schema_ranges(void **st)
{
    struct conf c, before;
    char err[320], want[320], v[32], expect[200];
    int ns, nint = 0;
    const struct conf_section *sec = conf_schema_sections(&ns);
    (void)st;
    for (int i = 0; i < ns; i++)
        for (int j = 0; j < sec[i].nkeys; j++) {
            const struct conf_key *k = &sec[i].keys[j];
            if (k->type != CONF_T_INT)
                continue;
            nint++;
            for (long x = k->lo; ; x = k->hi) {
                snprintf(v, sizeof v, "%ld", x);
                if (load_key(&sec[i], k, v, &c, err, sizeof err))
                    fail_msg("[%s] %s = %ld refused: %s", sec[i].name, k->name, x, err);
                assert_int_equal(stored(section_base(&c, &sec[i]), k), x);
                if (x == k->hi)
                    break;
            }
            conf_schema_expect(k, expect, sizeof expect);
            for (int e = 0; e < 2; e++) {
                conf_default(&before);
                snprintf(v, sizeof v, "%ld", e ? k->hi + 1 : k->lo - 1);
                assert_int_equal(load_key(&sec[i], k, v, &c, err, sizeof err), -1);
                assert_memory_equal(&c, &before, sizeof c);
                assert_non_null(strstr(err, "] "));
                snprintf(want, sizeof want, "%s: %s", k->name, expect);
                if (!strstr(err, want))
                    fail_msg("[%s] %s = %s: '%s' lacks '%s'", sec[i].name, k->name, v, err, want);
                (void)key_line_in;
            }
        }
    assert_true(nint >= 25);
    /* The messages the operators see, spelt out for a few. */
    conf_schema_expect(conf_schema_key(conf_schema_section("modbus"), "tcp_keepalive", NULL), expect, sizeof expect);
    assert_string_equal(expect, "expected seconds 0..7200 (0: off)");
    conf_schema_expect(conf_schema_key(conf_schema_section("rtu:a"), "t35_us", NULL), expect, sizeof expect);
    assert_string_equal(expect, "expected auto or microseconds 500..1000000");
    conf_schema_expect(conf_schema_key(conf_schema_section("model:1"), "n", NULL), expect, sizeof expect);
    assert_string_equal(expect, "expected 1..255 (bezier: 1..7)");
}

/* Every ENUM, BOOL and FLAG key: each listed word is taken and stored as
 * its code; a word one letter off is refused with "did you mean" it. */
static void test_schema_words(void **st)
{
    struct conf c;
    char err[320], want[320], v[64];
    int ns;
    const struct conf_section *sec = conf_schema_sections(&ns);
    static const struct conf_word yesno[] = { { "yes", 1, 0 }, { "no", 0, 0 }, { "on", 1, 1 }, { "off", 0, 1 },
                                              { "true", 1, 1 }, { "FALSE", 0, 1 }, { "1", 1, 1 }, { "0", 0, 1 },
                                              { NULL, 0, 0 } };
    (void)st;
    for (int i = 0; i < ns; i++)
        for (int j = 0; j < sec[i].nkeys; j++) {
            const struct conf_key *k = &sec[i].keys[j];
            const struct conf_word *w = k->type == CONF_T_BOOL || k->type == CONF_T_FLAG ? yesno : k->words;
            if (!w || (k->type == CONF_T_INT && !k->words))
                continue;
            for (; w->word; w++) {
                if (!strcmp(k->name, "default_model") || (!strcmp(k->name, "chord") && w->code) ||
                    (!strcmp(k->name, "kind") && 0))
                    continue; /* cross-key rules: tested in test_errors */
                if (!strcmp(k->name, "removed") && w->code)
                    continue; /* the only model removed: test_removed */
                if (load_key(&sec[i], k, w->word, &c, err, sizeof err))
                    fail_msg("[%s] %s = %s refused: %s", sec[i].name, k->name, w->word, err);
                assert_int_equal(stored(section_base(&c, &sec[i]), k), w->code);
                if (w->hidden || strlen(w->word) < 2)
                    continue;
                /* one letter off: the last one changed to another */
                snprintf(v, sizeof v, "%.*s%c", (int)strlen(w->word) - 1, w->word,
                         w->word[strlen(w->word) - 1] == 'q' ? 'j' : 'q');
                assert_int_equal(load_key(&sec[i], k, v, &c, err, sizeof err), -1);
                if (k->type == CONF_T_BOOL || k->type == CONF_T_FLAG) {
                    assert_non_null(strstr(err, ": expected yes or no"));
                    continue;
                }
                snprintf(want, sizeof want, ": did you mean '%s'?", conf_schema_suggest_word(k, v));
                assert_non_null(strstr(err, want));
                assert_string_equal(conf_schema_suggest_word(k, v), w->word);
            }
        }
    /* case is ignored; hidden aliases are taken but not offered */
    assert_int_equal(load("[rtu:a]\ndevice = /dev/null\nparity = O\n", &c, err, sizeof err), 0);
    assert_int_equal(c.rtu[0].parity, 'O');
    assert_int_equal(load("[modbus]\nfloat_word_order = cdab\n", &c, err, sizeof err), 0);
    assert_int_equal(c.word_order, 1);
    assert_null(conf_schema_suggest_word(conf_schema_key(conf_schema_section("rtu:a"), "parity", NULL), "X"));
}

/* Text keys: the longest value that fits is taken, one byte more is not. */
static void test_schema_lengths(void **st)
{
    struct conf c;
    char err[320], v[200];
    const struct conf_section *sp = conf_schema_section("sparkplug");
    (void)st;
    static const char *const keys[] = { "username", "group_id", "client_id", "primary_host_id" };
    for (size_t j = 0; j < sizeof keys / sizeof keys[0]; j++) {
        const struct conf_key *k = conf_schema_key(sp, keys[j], NULL);
        assert_non_null(k);
        assert_true(k->size < sizeof v);
        memset(v, 'x', k->size - 1);
        v[k->size - 1] = 0;
        if (load_key(sp, k, v, &c, err, sizeof err))
            fail_msg("%s of %zu bytes refused: %s", keys[j], k->size - 1, err);
        assert_string_equal((const char *)section_base(&c, sp) + k->off, v);
        v[k->size - 1] = 'x';
        v[k->size] = 0;
        assert_int_equal(load_key(sp, k, v, &c, err, sizeof err), -1);
        assert_non_null(strstr(err, "expected 1.."));
    }
}

/* The table itself: unique names, help on every key, sound ranges, and
 * defaults that are values of their keys, which conf_default applies. */
static void test_schema_table(void **st)
{
    struct conf c;
    int ns;
    const struct conf_section *sec = conf_schema_sections(&ns);
    (void)st;
    conf_default(&c);
    assert_int_equal(ns, 8);
    for (int i = 0; i < ns; i++) {
        assert_true(sec[i].nkeys >= 1 && sec[i].nkeys <= CONF_SCHEMA_MAX_KEYS);
        assert_true(sec[i].needs && sec[i].needs[0] && sec[i].title);
        assert_ptr_equal(conf_schema_section(sec[i].arg ? "x" : sec[i].name), sec[i].arg ? NULL : &sec[i]);
        for (int l = 0; l < i; l++)
            assert_string_not_equal(sec[i].name, sec[l].name);
        for (int j = 0; j < sec[i].nkeys; j++) {
            const struct conf_key *k = &sec[i].keys[j];
            long x;
            assert_true(k->help && k->help[0]);
            assert_null(strchr(k->help, '\n'));
            assert_null(strchr(k->help, '|')); /* a markdown table cell */
            for (int l = 0; l < j; l++) {
                const struct conf_key *o = &sec[i].keys[l];
                assert_string_not_equal(k->name, o->name);
                /* two keys stored in one place: one would overwrite the
                 * other (a copied entry with its offset left unchanged) */
                if (k->size && o->size && k->off == o->off && k->bit == o->bit)
                    fail_msg("[%s] %s and %s are stored in the same field", sec[i].name, o->name, k->name);
                if (k->line_off && k->line_off == o->line_off)
                    fail_msg("[%s] %s and %s keep their line in the same field", sec[i].name, o->name, k->name);
            }
            if (k->type == CONF_T_INT)
                assert_true(k->lo <= k->hi);
            if (k->type == CONF_T_ENUM)
                assert_non_null(k->words);
            if (k->def && k->type <= CONF_T_FLAG) {
                /* the default is a value of the key, and conf_default's
                 * (the default model's for [model:]) */
                assert_int_equal(conf_schema_number(k, k->def, &x), 0);
                if (sec[i].id == CONF_SEC_DAEMON || sec[i].id == CONF_SEC_MODBUS || sec[i].id == CONF_SEC_MODEL ||
                    sec[i].id == CONF_SEC_SPARKPLUG)
                    assert_int_equal(stored(section_base(&c, &sec[i]), k),
                                     strcmp(k->name, "preload") ? x : 1); /* the default model is the paper's */
            }
            if (!k->def && !k->def_doc)
                assert_true(k->type >= CONF_T_STR); /* the docs say nothing: an optional text */
        }
    }
}

/* daemon/it2nd.conf.example, the commented example installed next to the
 * configuration, shows every key of the schema ("key =", ";key =" or "; key =" at
 * the start of a line). */
static void test_schema_example(void **st)
{
    FILE *f = fopen("daemon/it2nd.conf.example", "r");
    static char ex[64 * 1024];
    int ns;
    const struct conf_section *sec = conf_schema_sections(&ns);
    (void)st;
    if (!f) {
        print_message("test_schema_example: skip: daemon/it2nd.conf.example not found (run from the source tree)\n");
        skip();
    }
    ex[0] = '\n';
    ex[1 + fread(ex + 1, 1, sizeof ex - 2, f)] = 0;
    fclose(f);
    for (int i = 0; i < ns; i++)
        for (int j = 0; j < sec[i].nkeys; j++) {
            char a[64], b[64], c[64];
            snprintf(a, sizeof a, "\n%s =", sec[i].keys[j].name);
            snprintf(b, sizeof b, "\n;%s =", sec[i].keys[j].name);
            snprintf(c, sizeof c, "\n; %s =", sec[i].keys[j].name);
            if (!strstr(ex, a) && !strstr(ex, b) && !strstr(ex, c))
                fail_msg("daemon/it2nd.conf.example does not show [%s%s] %s", sec[i].name,
                         sec[i].arg ? sec[i].arg : "", sec[i].keys[j].name);
        }
}

/* docs/daemon.md holds the schema's tables as it2nd --config-keys=markdown
 * prints them (generated by `make docs-figures`; docs-check fails on a
 * stale one too). */
static void test_schema_docs(void **st)
{
    FILE *f = fopen("docs/daemon.md", "r"), *t = tmpfile();
    static char doc[256 * 1024], ref[64 * 1024];
    size_t n, m;
    (void)st;
    if (!f) {
        print_message("test_schema_docs: skip: docs/daemon.md not found (run from the source tree)\n");
        skip();
    }
    n = fread(doc, 1, sizeof doc - 1, f);
    fclose(f);
    doc[n] = 0;
    assert_non_null(t);
    assert_int_equal(conf_schema_print(t, "markdown"), 0);
    rewind(t);
    m = fread(ref, 1, sizeof ref - 1, t);
    fclose(t);
    ref[m] = 0;
    assert_int_equal(conf_schema_print(stdout, "nonsense"), -1);
    /* Each section's heading and table, verbatim. */
    for (char *h = ref; (h = strstr(h, "### ")) != NULL;) {
        char *end = strstr(h + 4, "\n### ");
        char save = 0;
        if (end) { /* up to the table's last line, without the blank line */
            save = end[0];
            end[0] = 0;
        }
        if (!strstr(doc, h))
            fail_msg("docs/daemon.md lacks (or has another version of) this table; run make docs-figures:\n%s", h);
        if (!end)
            break;
        end[0] = save;
        h = end + 1;
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_default),
        cmocka_unit_test(test_suggestions),
        cmocka_unit_test(test_metrics_section),
        cmocka_unit_test(test_same_sections),
        cmocka_unit_test(test_override),
        cmocka_unit_test(test_full),
        cmocka_unit_test(test_errors),
        cmocka_unit_test(test_kind),
        cmocka_unit_test(test_repeat_and_hosts),
        cmocka_unit_test(test_rs485),
        cmocka_unit_test(test_unreadable_and_empty),
        cmocka_unit_test(test_partial_files),
        cmocka_unit_test(test_removed),
        cmocka_unit_test(test_device_conflicts),
        cmocka_unit_test(test_listen_acl),
        cmocka_unit_test(test_schema_table),
        cmocka_unit_test(test_schema_ranges),
        cmocka_unit_test(test_schema_words),
        cmocka_unit_test(test_schema_lengths),
        cmocka_unit_test(test_schema_docs),
        cmocka_unit_test(test_schema_example),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
