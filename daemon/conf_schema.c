/* conf_schema.c — see conf_schema.h. The help texts are the key tables of
 * docs/daemon.md (generated from here: edit them here, then run
 * `make docs-figures`). */
#include "conf_schema.h"

#include <ctype.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "conf.h"
#include "it2n.h"
#include "it2n_regmap.h"
#include "loop.h"

#define F(T, f) .off = offsetof(struct T, f), .size = sizeof(((struct T *)0)->f)
#define LINE(T, f) .line_off = offsetof(struct T, f) + 1
#define STR_(x) #x
#define STR(x) STR_(x)

/* clang-format off */
static const struct conf_word w_order[] = {
    { "ABCD", IT2N_REGMAP_WO_ABCD, 0 }, { "CDAB", IT2N_REGMAP_WO_CDAB, 0 }, { "BADC", IT2N_REGMAP_WO_BADC, 0 }, { "DCBA", IT2N_REGMAP_WO_DCBA, 0 },
    { NULL, 0, 0 }
};
static const struct conf_word w_order32[] = {
    { "float", -1, 0 }, { "ABCD", IT2N_REGMAP_WO_ABCD, 0 }, { "CDAB", IT2N_REGMAP_WO_CDAB, 0 }, { "BADC", IT2N_REGMAP_WO_BADC, 0 },
    { "DCBA", IT2N_REGMAP_WO_DCBA, 0 }, { NULL, 0, 0 }
};
static const struct conf_word w_default_model[] = {
    { "auto", CONF_DEFAULT_AUTO, 0 }, { "none", CONF_DEFAULT_NONE, 0 }, { NULL, 0, 0 }
};
static const struct conf_word w_parity[] = {
    { "none", 'N', 0 }, { "even", 'E', 0 }, { "odd", 'O', 0 },
    { "N", 'N', 1 }, { "E", 'E', 1 }, { "O", 'O', 1 }, { NULL, 0, 0 }
};
static const struct conf_word w_io[] = {
    { "auto", LOOP_IO_AUTO, 0 }, { "io_uring", LOOP_IO_URING, 0 }, { "epoll", LOOP_IO_EPOLL, 0 }, { NULL, 0, 0 }
};
static const struct conf_word w_auto0[] = { { "auto", 0, 0 }, { NULL, 0, 0 } };
static const struct conf_word w_rts[] = {
    { "none", CONF_RTS_NONE, 0 }, { "up", CONF_RTS_UP, 0 }, { "down", CONF_RTS_DOWN, 0 }, { NULL, 0, 0 }
};
static const struct conf_word w_rts_on_send[] = { { "high", 1, 0 }, { "low", 0, 0 }, { NULL, 0, 0 } };
static const struct conf_word w_kind[] = {
    { "bezier", CONF_KIND_BEZIER, 0 }, { "bspline", CONF_KIND_BSPLINE, 0 }, { NULL, 0, 0 }
};
static const struct conf_word w_preload[] = { { "paper", 1, 0 }, { "none", 0, 0 }, { NULL, 0, 0 } };
static const struct conf_word w_link_type[] = {
    { "serial", CONF_LINK_SERIAL, 0 }, { "usb", CONF_LINK_USB, 0 }, { NULL, 0, 0 }
};

static const struct conf_key k_daemon[] = {
    { .name = "state_dir", .type = CONF_T_PATH, F(conf, state_dir), .def = "./state", .flags = CONF_K_RESTART,
      .help = "WAL and snapshot directory (created). Under systemd: `/var/lib/it2n`" },
    { .name = "snapshot_interval", .type = CONF_T_INT, .lo = 1, .hi = 86400, .unit = "seconds",
      F(conf, snapshot_interval), .def = "60", .help = "seconds between snapshots (only if the WAL has records)" },
    { .name = "fsync", .type = CONF_T_BOOL, F(conf, fsync), .def = "yes",
      .help = "fdatasync the WAL before acknowledging; `no` is for tests only" },
    { .name = "io", .type = CONF_T_ENUM, .words = w_io, F(conf, io), .def = "auto", .flags = CONF_K_RESTART,
      .help = "how the event loop waits and moves Modbus TCP data: `io_uring` (one system call per wake-up carries "
              "every read and reply), `epoll` (a wait, then a recv and a send per request), or `auto`: io_uring "
              "unless the kernel refuses it (too old, `kernel.io_uring_disabled`, a seccomp filter), then epoll. "
              "The log's start line names the one in use. Explicit `io_uring` that the kernel refuses stops the "
              "start with the reason" },
    { .name = "max_models", .type = CONF_T_INT, .lo = 1, .hi = CONF_MAX_MODELS, F(conf, max_models), .def = "8",
      .help = "models this daemon may serve" },
    { .name = "link_backoff_max", .type = CONF_T_INT, .lo = 1, .hi = 3600, .unit = "seconds",
      F(conf, link_backoff_max), .def = "30",
      .help = "longest wait (s) between reopen attempts of a failed link; backoff starts at 0.5 s and doubles" },
    { .name = "user", .type = CONF_T_USER, F(conf, user), .def_doc = "(unset)", .flags = CONF_K_RESTART,
      .help = "when started as root: drop to this user after opening everything that needs root (below). An "
              "unknown user is a fatal config error with file:line. Started as root without it, the daemon logs a "
              "warning (`running as root: set user = NAME ...`) and stays root" },
};

static const struct conf_key k_modbus[] = {
    { .name = "tcp_listen", .type = CONF_T_LISTEN, .def = "127.0.0.1:1502", .flags = CONF_K_REPEAT,
      .help = "repeatable: `host:port`, `[v6]:port`, `:port` (dual-stack any), or `none`. Port 502 needs "
              "`CAP_NET_BIND_SERVICE` (the unit grants it)" },
    { .name = "max_clients", .type = CONF_T_INT, .lo = 1, .hi = 512, F(conf, max_clients), .def = "32",
      .help = "TCP connection slots: a connection takes one with its first complete request; when all are taken "
              "that request waits for one (\"Connection slots\" below)" },
    { .name = "max_pending", .type = CONF_T_INT, .lo = 16, .hi = 65536, F(conf, max_pending), .def = "1024",
      .help = "TCP connections without a slot (no complete request yet, or waiting for a slot); also limited by "
              "`RLIMIT_NOFILE`, which the daemon raises towards its hard limit. When full, a connection without a "
              "complete request is closed for a new one, never one with a request (\"Connection slots\")" },
    { .name = "evict_idle", .type = CONF_T_INT, .lo = 0, .hi = 86400000, .unit = "milliseconds",
      F(conf, evict_idle), .def = "500",
      .help = "ms without a request after which a connection may lose its slot to a new client when all slots "
              "are taken" },
    { .name = "idle_timeout", .type = CONF_T_INT, .lo = 1, .hi = 86400, .unit = "seconds", F(conf, idle_timeout),
      .def = "300", .help = "seconds without a request before a client is closed" },
    { .name = "byte_timeout", .type = CONF_T_INT, .lo = 10, .hi = 60000, .unit = "milliseconds",
      F(conf, byte_timeout), .def = "500",
      .help = "ms a started request may take to arrive completely (up to 800 keeps the 1 s guarantee below)" },
    { .name = "tcp_keepalive", .type = CONF_T_INT, .lo = 0, .hi = 7200, .unit = "seconds", .note = "0: off",
      F(conf, tcp_keepalive), .def = "60",
      .help = "TCP keepalive on accepted connections: seconds idle before the first probe, then up to 3 probes at "
              "most 10 s apart (`TCP_KEEPIDLE`/`KEEPINTVL`/`KEEPCNT`, and `TCP_USER_TIMEOUT` of the same total for "
              "unacknowledged replies)" },
    { .name = "float_word_order", .type = CONF_T_ENUM, .words = w_order, F(conf, word_order), .def = "ABCD",
      .help = "float32 register order" },
    { .name = "int32_word_order", .type = CONF_T_ENUM, .words = w_order32, F(conf, int32_word_order),
      .def = "float",
      .help = "order of the u32/i32 registers (generation, counters, scaled coordinates): `float` = the same as "
              "`float_word_order` (a CDAB PLC sees one order); readable in status register 27" },
    { .name = "default_model", .type = CONF_T_INT, .lo = 0, .hi = 254, .words = w_default_model,
      .unit = "a model id", F(conf, default_model), .def = "auto",
      .help = "the model Modbus TCP unit ids 0 and 255 reach (255 is the Modbus TCP spec's id for \"this "
              "server\", and many clients send it or 0): `auto` = the only model when exactly one is configured "
              "(the built-in default), else none; `none` (0B, as for any unknown unit); or a configured model id. "
              "RTU is unchanged (0 is broadcast)" },
    { .name = "coord_scale", .type = CONF_T_INT, .lo = 1, .hi = 10000, F(conf, coord_scale), .def = "100",
      .help = "scaled-integer coordinates: register = value x scale" },
    { .name = "grid_rows", .type = CONF_T_INT, .lo = 2, .hi = 16, F(conf, grid_rows), .def = "5",
      .help = "rows of the sample grid block; rows x cols at most 256 nodes" },
    { .name = "grid_cols", .type = CONF_T_INT, .lo = 2, .hi = 16, F(conf, grid_cols), .def = "5",
      .help = "columns of the sample grid block" },
};

static const struct conf_key k_listen[] = {
    { .name = "address", .type = CONF_T_ADDR, .def_doc = "(required)", .flags = CONF_K_REQUIRED,
      .help = "as `tcp_listen`: `host:port`, `[v6]:port`, `:port`" },
    { .name = "allow", .type = CONF_T_ALLOW, .def_doc = "everyone", .flags = CONF_K_REPEAT,
      .help = "repeatable, comma- or space-separated: numeric IPv4/IPv6 addresses and prefixes (`10.1.0.0/16`, "
              "`192.168.7.5`, `fd00::/8`, `[::1]`), at most " STR(CONF_MAX_ALLOW) ". A client whose address "
              "matches none is closed at accept, before a byte is read. An IPv4 client of a dual-stack (`:port`) "
              "listener is matched as IPv4. Host names are refused (no DNS in an access decision); host bits "
              "beyond the prefix are an error (`10.0.0.1/8`)" },
    { .name = "read_only", .type = CONF_T_BOOL, F(conf_listen, read_only), .def = "no",
      .help = "`yes`: writes that would change a model (configuration block 32..35, upload block 40..51) get "
              "exception 02; reads and queries (query registers 64..77, FC 23) work" },
};

static const struct conf_key k_rtu[] = {
    { .name = "device", .type = CONF_T_PATH, F(conf_rtu, device), LINE(conf_rtu, device_line),
      .def_doc = "(required)", .flags = CONF_K_REQUIRED, .help = "serial device" },
    { .name = "baud", .type = CONF_T_INT, .lo = 1200, .hi = 4000000, F(conf_rtu, baud), .def = "19200",
      .help = "bits per second" },
    { .name = "parity", .type = CONF_T_ENUM, .words = w_parity, F(conf_rtu, parity), .def = "even",
      .help = "`N`, `E`, `O` are taken too" },
    { .name = "stop_bits", .type = CONF_T_INT, .lo = 1, .hi = 2, F(conf_rtu, stop_bits), .def = "1",
      .help = "stop bits" },
    { .name = "read_only", .type = CONF_T_BOOL, F(conf_rtu, read_only), .def = "no",
      .help = "`yes`: writes that would change a model get exception 02 on this port, as on a read-only TCP "
              "listener (\"Access control\")" },
    { .name = "t35_us", .type = CONF_T_INT, .lo = 500, .hi = 1000000, .words = w_auto0, .unit = "microseconds",
      F(conf_rtu, t35_us), .def = "auto",
      .help = "inter-frame silence: `auto` = t3.5 of the Modbus serial line spec (3.5 character times of this "
              "port's frame up to 19200 Bd, e.g. 2005 µs at 19200 8E1, 4011 µs at 9600 8E1; 1750 µs above 19200), "
              "or µs (a USB adapter that holds bytes back, e.g. an FTDI with its 16 ms latency timer, may need "
              "more; lowering its `latency_timer` to 1 ms is better). See \"RTU framing\"" },
    { .name = "rs485", .type = CONF_T_BOOL, F(conf_rtu, rs485), .def = "no",
      .help = "`yes`: RS-485 half duplex (below). `no` leaves the port's RS-485 state as the driver has it (e.g. "
              "device tree `linux,rs485-enabled-at-boot-time`)" },
    { .name = "rs485_rts", .type = CONF_T_ENUM, .words = w_rts, F(conf_rtu, rts), .def = "none",
      .flags = CONF_K_RS485,
      .help = "who switches the transceiver through RTS: `none` the kernel driver (RS-485 mode, `TIOCSRS485` via "
              "`modbus_rtu_set_serial_mode`), `up`/`down` libmodbus (`modbus_rtu_set_rts`: RTS raised/lowered "
              "while a reply is sent)" },
    { .name = "rs485_rts_delay_us", .type = CONF_T_INT, .lo = 0, .hi = CONF_RTS_DELAY_US_MAX,
      .unit = "microseconds", F(conf_rtu, rts_delay_us), .unset = -1, .def_doc = "one character",
      .flags = CONF_K_RS485 | CONF_K_LIBMODBUS,
      .help = "libmodbus RTS only: µs between RTS and the first byte, and after the last one "
              "(`modbus_rtu_set_rts_delay`)" },
    { .name = "rs485_rts_on_send", .type = CONF_T_ENUM, .words = w_rts_on_send, F(conf_rtu, rts_on_send),
      .unset = -1, .def_doc = "driver's", .flags = CONF_K_RS485 | CONF_K_KERNEL,
      .help = "kernel only: RTS level while sending, `high` (`SER_RS485_RTS_ON_SEND`) or `low` "
              "(`SER_RS485_RTS_AFTER_SEND`)" },
    { .name = "rs485_delay_before_send_ms", .type = CONF_T_INT, .lo = 0, .hi = CONF_RS485_DELAY_MS_MAX,
      .unit = "milliseconds", .note = "the kernel's limit", F(conf_rtu, delay_before_ms), .unset = -1,
      .def_doc = "driver's", .flags = CONF_K_RS485 | CONF_K_KERNEL,
      .help = "kernel only: `delay_rts_before_send`" },
    { .name = "rs485_delay_after_send_ms", .type = CONF_T_INT, .lo = 0, .hi = CONF_RS485_DELAY_MS_MAX,
      .unit = "milliseconds", .note = "the kernel's limit", F(conf_rtu, delay_after_ms), .unset = -1,
      .def_doc = "driver's", .flags = CONF_K_RS485 | CONF_K_KERNEL, .help = "kernel only: `delay_rts_after_send`" },
    { .name = "rs485_termination", .type = CONF_T_BOOL, F(conf_rtu, termination), .unset = -1,
      .def_doc = "driver's", .flags = CONF_K_RS485 | CONF_K_KERNEL,
      .help = "kernel only: bus termination (`SER_RS485_TERMINATE_BUS`, where the driver has a termination GPIO)" },
    { .name = "rs485_strict", .type = CONF_T_BOOL, F(conf_rtu, strict), .def = "no", .flags = CONF_K_RS485,
      .help = "`yes`: a device that refuses any RS-485 setting is not served (below)" },
};

static const struct conf_key k_model[] = {
    { .name = "unit_id", .type = CONF_T_INT, .lo = 1, .hi = 247, F(conf_model, unit), .def_doc = "ID",
      .help = "Modbus unit id (required for ID 0 and above 247)" },
    { .name = "kind", .type = CONF_T_ENUM, .words = w_kind, F(conf_model, kind), .def = "bezier",
      .set = CONF_SET_KIND,
      .help = "`bezier`: one Bezier patch through the grid (the paper's method); `bspline`: tensor-product cubic "
              "B-spline through every point, not-a-knot, uniform parameters (firmware_core/it2n.h, "
              "docs/numerics.md)" },
    { .name = "n", .type = CONF_T_INT, .lo = 1, .hi = IT2N_BSPLINE_MAX_N, .note = "bezier: 1.." STR(IT2N_MAX_DEGREE),
      F(conf_model, n), .set = CONF_SET_N, .def = "3",
      .help = "`bezier`: degree 1.." STR(IT2N_MAX_DEGREE) "; `bspline`: intervals (a grid of n+1 points), which "
              "also size the model's storage: a CONFIGURE may later choose any grid up to n x m, not more" },
    { .name = "m", .type = CONF_T_INT, .lo = 1, .hi = IT2N_BSPLINE_MAX_N, .note = "bezier: 1.." STR(IT2N_MAX_DEGREE),
      F(conf_model, m), .set = CONF_SET_M, .def = "3", .help = "as `n`, in the other direction" },
    { .name = "z", .type = CONF_T_FLAG, F(conf_model, flags), .bit = IT2N_F_Z, .set = CONF_SET_Z, .def = "no",
      .help = "coordinates with z" },
    { .name = "type1", .type = CONF_T_FLAG, F(conf_model, flags), .bit = IT2N_F_TYPE1, .set = CONF_SET_TYPE1,
      .def = "no", .help = "footprint D only" },
    { .name = "chord", .type = CONF_T_FLAG, F(conf_model, flags), .bit = IT2N_F_CHORD, .set = CONF_SET_CHORD,
      .def = "no", .help = "chord-length parameters (`bezier` only)" },
    { .name = "write_protect", .type = CONF_T_BOOL, F(conf_model, write_protect), .def = "no",
      .help = "`yes`: no Modbus write may change this model: writes to its configuration and upload registers get "
              "exception 02 on every listener and RTU port; queries work; instrument links may still change it" },
    { .name = "preload", .type = CONF_T_ENUM, .words = w_preload, F(conf_model, preload), .def = "none",
      .def_doc = "none (`paper` for the default model)",
      .help = "`paper`: the built-in 4x4 example (needs n = m = 3)" },
    { .name = "removed", .type = CONF_T_BOOL, F(conf_model, removed), .def = "no",
      .help = "`yes`: the model is taken out of service and **its data are discarded** (at the next reload, or at "
              "start for data in the state directory); the other keys of the section are ignored, its unit id is "
              "free, it does not count in `max_models`. The only way to remove a model that holds data (see "
              "\"Reload (SIGHUP)\"); at least one model must remain" },
};

static const struct conf_key k_link[] = {
    { .name = "type", .type = CONF_T_ENUM, .words = w_link_type, F(conf_link, type), .def = "serial",
      .help = "`serial` or `usb`" },
    { .name = "device", .type = CONF_T_PATH, F(conf_link, device), LINE(conf_link, device_line),
      .def_doc = "(required: serial)",
      .help = "tty path (`/dev/ttyACM0`, `/dev/serial/by-id/...`), opened raw" },
    { .name = "baud", .type = CONF_T_INT, .lo = 1200, .hi = 4000000, F(conf_link, baud), .def = "115200",
      .help = "bits per second" },
    { .name = "usb", .type = CONF_T_USB, .def_doc = "(required: usb)",
      .help = "`VID:PID[:serial]` in hex; interface 0, first bulk IN and OUT endpoints" },
    { .name = "rto_ms", .type = CONF_T_INT, .lo = 1, .hi = 60000, .unit = "milliseconds", F(conf_link, rto_ms),
      .def_doc = "from `baud`",
      .help = "first retransmission timeout of the daemon's frames, counted on a serial link from when the frame "
              "has left the line (estimated from the bytes written before it and `baud`; a due retransmission also "
              "waits while the peer's bytes keep arriving, at most the time W maximum frames take, W the daemon's "
              "window, 16; protocol.md 4.2 rule 3; with the line clock a new frame is written only while at most "
              "two maximum frames wait on the line, rule 2); default 20 ms + the time one maximum frame (1046 "
              "bytes) takes at `baud`: 32 ms at 921600, 111 ms at 115200, 1110 ms at 9600; 100 ms on USB (from the "
              "write). It is the minimum: the link raises its RTO above it when the measured round trips call "
              "for it (SRTT + 4 RTTVAR, answers to frames sent once only; protocol.md 4.2 rule 3). On a serial "
              "link the first 3 retransmissions keep the RTO, on USB it doubles from the second; "
              "then it doubles each time up to 8 × `rto_ms`" },
    { .name = "peer_timeout_ms", .type = CONF_T_INT, .lo = 100, .hi = 3600000, .unit = "milliseconds",
      F(conf_link, peer_timeout_ms), .def = "30000",
      .help = "a frame unanswered this long: the link is declared down, the daemon's frames in flight and queued "
              "responses are dropped, and the peer gets EVENT LOST (protocol.md 5.10) when it speaks again" },
};

static const struct conf_key k_sparkplug[] = {
    { .name = "broker", .type = CONF_T_BROKER, .def_doc = "(required)", .flags = CONF_K_RESTART | CONF_K_REQUIRED,
      .help = "the MQTT server: `host:port`, `[v6addr]:port` or `host` (port 1883). A host name is resolved at "
              "each connection attempt (docs/sparkplug.md, \"Never stalls the cell\")" },
    { .name = "group_id", .type = CONF_T_SPB_ID, F(spb_conf, group_id), .def_doc = "(required)",
      .flags = CONF_K_RESTART | CONF_K_REQUIRED,
      .help = "Sparkplug group id: printable ASCII, no `/`, `+`, `#` (one topic level)" },
    { .name = "edge_node_id", .type = CONF_T_SPB_ID, F(spb_conf, edge_node_id), .def_doc = "(required)",
      .flags = CONF_K_RESTART | CONF_K_REQUIRED,
      .help = "Sparkplug edge node id, same rules; unique in the group (spec 6.4.1)" },
    { .name = "client_id", .type = CONF_T_SPB_ID, F(spb_conf, client_id),
      .def_doc = "`it2nd-<group_id>-<edge_node_id>`", .flags = CONF_K_RESTART, .help = "MQTT client id, same rules" },
    { .name = "keepalive", .type = CONF_T_INT, .lo = 5, .hi = 3600, .unit = "seconds", F(spb_conf, keepalive),
      .def = "30", .flags = CONF_K_RESTART,
      .help = "MQTT keep alive. A broker silent for this long after a PINGREQ, or a CONNACK that does not come "
              "within it, drops the connection and the node reconnects" },
    { .name = "reconnect_max", .type = CONF_T_INT, .lo = 1, .hi = 3600, .unit = "seconds",
      F(spb_conf, reconnect_max), .def = "30", .flags = CONF_K_RESTART,
      .help = "the longest wait between connection attempts; the wait starts at 0.5 s and doubles" },
    { .name = "username", .type = CONF_T_STR, F(spb_conf, username), .flags = CONF_K_RESTART,
      .help = "MQTT user name" },
    { .name = "password_file", .type = CONF_T_SECRET, LINE(spb_conf, password_line), .flags = CONF_K_RESTART,
      .help = "a file whose first line is the MQTT password (read at start, so a missing or empty file is a "
              "configuration error with its line; needs `username`)" },
    { .name = "tls_ca", .type = CONF_T_FILE, F(spb_conf, tls_ca), LINE(spb_conf, tls_ca_line),
      .flags = CONF_K_RESTART,
      .help = "CA certificates (PEM) that sign the broker's certificate: the connection is TLS, the broker's chain "
              "and host name (as written in `broker`, e.g. an IP address in its subjectAltName) are verified" },
    { .name = "tls_cert", .type = CONF_T_FILE, F(spb_conf, tls_cert), LINE(spb_conf, tls_cert_line),
      .flags = CONF_K_RESTART,
      .help = "a client certificate (PEM chain), for brokers that require one (`require_certificate true`); "
              "needs `tls_key` and `tls_ca`" },
    { .name = "tls_key", .type = CONF_T_FILE, F(spb_conf, tls_key), LINE(spb_conf, tls_key_line),
      .flags = CONF_K_RESTART, .help = "the key of `tls_cert` (PEM, not encrypted)" },
    { .name = "primary_host_id", .type = CONF_T_SPB_ID, F(spb_conf, primary_host_id), .flags = CONF_K_RESTART,
      .help = "the Sparkplug host id of the primary host application, same rules as the ids: the node follows its "
              "STATE and is born only while it is online (docs/sparkplug.md, \"Primary host and "
              "store-and-forward\")" },
    { .name = "store_forward_max", .type = CONF_T_INT, .lo = 0, .hi = SPB_SF_LIMIT,
      .unit = "a number of stored changes", .note = "0: none kept", F(spb_conf, store_forward), .unset = -1,
      .def_doc = STR(SPB_SF_DEFAULT) " with `primary_host_id`, else 0", .flags = CONF_K_RESTART,
      .help = "changes kept in the state directory while the primary host or the broker is away (0: none kept, "
              "the births after the return carry the current values only)" },
};

static const struct conf_key k_metrics[] = {
    { .name = "listen", .type = CONF_T_ENDPOINT, LINE(conf_metrics, line), .def_doc = "(off)",
      .flags = CONF_K_RESTART,
      .help = "`HOST:PORT` of the Prometheus endpoint (GET `/metrics`), `[v6]:PORT`, `:PORT`, or `none`; not a "
              "Modbus listener's address. See \"Metrics\"" },
};

#define KEYS(a) a, (int)(sizeof a / sizeof a[0])
static const struct conf_section sections[] = {
    { "daemon", CONF_SEC_DAEMON, NULL, "", "a section with no keys has no effect; remove it or add keys", 0,
      KEYS(k_daemon) },
    { "modbus", CONF_SEC_MODBUS, NULL, "", "a section with no keys has no effect; remove it or add keys", 0,
      KEYS(k_modbus) },
    { "listen:", CONF_SEC_LISTEN, "NAME", " (any number): a TCP listener with an access policy",
      "address is required", 0, KEYS(k_listen) },
    { "rtu:", CONF_SEC_RTU, "NAME", " (any number): a Modbus RTU port", "device is required", 0, KEYS(k_rtu) },
    { "model:", CONF_SEC_MODEL, "ID", " (ID 0..254, the model id on the links)",
      "a model needs at least one of unit_id, kind, n, m, z, type1, chord, preload; without any the section "
      "would be ignored", offsetof(struct conf_model, set) + 1, KEYS(k_model) },
    { "link:", CONF_SEC_LINK, "NAME", " (any number): an instrument link",
      "type and device (serial) or usb (usb) are required", 0, KEYS(k_link) },
    { "sparkplug", CONF_SEC_SPARKPLUG, NULL, " (optional): a Sparkplug B edge node on MQTT",
      "broker, group_id and edge_node_id are required", 0, KEYS(k_sparkplug) },
    { "metrics", CONF_SEC_METRICS, NULL, ": the Prometheus endpoint",
      "a section with no keys has no effect; remove it or add keys", 0, KEYS(k_metrics) },
};
#define NSECTIONS ((int)(sizeof sections / sizeof sections[0]))
/* clang-format on */

const struct conf_section *conf_schema_sections(int *n)
{
    *n = NSECTIONS;
    return sections;
}

const struct conf_section *conf_schema_section(const char *header)
{
    for (int k = 0; k < NSECTIONS; k++) {
        const char *name = sections[k].name;
        size_t n = strlen(name);
        if (sections[k].arg ? !strncmp(header, name, n) && header[n] : !strcmp(header, name))
            return &sections[k];
    }
    return NULL;
}

const struct conf_key *conf_schema_key(const struct conf_section *s, const char *name, int *idx)
{
    for (int k = 0; s && k < s->nkeys; k++)
        if (!strcmp(s->keys[k].name, name)) {
            if (idx)
                *idx = k;
            return &s->keys[k];
        }
    return NULL;
}

/* Edit distance with transpositions (optimal string alignment), case
 * folded; names longer than 40 characters are never close. */
static int distance(const char *a, const char *b)
{
    int d[42][42];
    int la = (int)strlen(a), lb = (int)strlen(b);
    if (la > 40 || lb > 40)
        return 99;
    for (int i = 0; i <= la; i++)
        d[i][0] = i;
    for (int j = 0; j <= lb; j++)
        d[0][j] = j;
    for (int i = 1; i <= la; i++)
        for (int j = 1; j <= lb; j++) {
            int ca = tolower((unsigned char)a[i - 1]), cb = tolower((unsigned char)b[j - 1]);
            int v = d[i - 1][j - 1] + (ca != cb);
            if (d[i - 1][j] + 1 < v)
                v = d[i - 1][j] + 1;
            if (d[i][j - 1] + 1 < v)
                v = d[i][j - 1] + 1;
            if (i > 1 && j > 1 && ca == tolower((unsigned char)b[j - 2]) && tolower((unsigned char)a[i - 2]) == cb &&
                d[i - 2][j - 2] + 1 < v)
                v = d[i - 2][j - 2] + 1;
            d[i][j] = v;
        }
    return d[la][lb];
}

/* Close enough to be a typo: one edit in a short name, two in a longer;
 * better than *best (then *best is updated). */
static int close_to(const char *name, const char *cand, int *best)
{
    int d = distance(name, cand), lim = strlen(cand) <= 4 ? 1 : 2;
    if (strlen(cand) == 1 && strlen(name) == 1 && tolower((unsigned char)name[0]) != tolower((unsigned char)cand[0]))
        return 0; /* "x" is not a typo of "n" */
    if (d > lim || d >= *best)
        return 0;
    *best = d;
    return 1;
}

const char *conf_schema_suggest_key(const struct conf_section *s, const char *name, const struct conf_section **where)
{
    const char *hit = NULL;
    int best = 99;
    *where = NULL;
    for (int k = 0; s && k < s->nkeys; k++)
        if (close_to(name, s->keys[k].name, &best))
            hit = s->keys[k].name;
    if (hit)
        return hit;
    /* A key of another section, written in the wrong one. */
    for (int j = 0; j < NSECTIONS; j++) {
        if (&sections[j] == s)
            continue;
        for (int k = 0; k < sections[j].nkeys; k++)
            if (!strcasecmp(name, sections[j].keys[k].name)) {
                *where = &sections[j];
                return sections[j].keys[k].name;
            }
    }
    return NULL;
}

const struct conf_section *conf_schema_suggest_section(const char *header)
{
    const struct conf_section *hit = NULL;
    const char *colon = strchr(header, ':');
    char kind[64];
    int best = 99;
    snprintf(kind, sizeof kind, "%.*s", colon ? (int)(colon - header + 1) : (int)strlen(header), header);
    for (int k = 0; k < NSECTIONS; k++)
        if (close_to(kind, sections[k].name, &best))
            hit = &sections[k];
    return hit;
}

const char *conf_schema_suggest_word(const struct conf_key *k, const char *value)
{
    const char *hit = NULL;
    int best = 99;
    for (int j = 0; k->words && k->words[j].word; j++)
        if (!k->words[j].hidden && close_to(value, k->words[j].word, &best))
            hit = k->words[j].word;
    return hit;
}

static int parse_bool(const char *v, long *out)
{
    static const char *const yes[] = {"yes", "true", "on", "1"}, *const no[] = {"no", "false", "off", "0"};
    for (int k = 0; k < 4; k++) {
        if (!strcasecmp(v, yes[k])) {
            *out = 1;
            return 0;
        }
        if (!strcasecmp(v, no[k])) {
            *out = 0;
            return 0;
        }
    }
    return -1;
}

/* A whole decimal number in [lo, hi], nothing around it. 0, or -1. */
static int decimal(const char *v, long lo, long hi, long *out)
{
    char *end;
    long x;
    errno = 0;
    x = strtol(v, &end, 10);
    if (!*v || *end || errno || x < lo || x > hi)
        return -1;
    *out = x;
    return 0;
}

int conf_schema_int(const char *v, int lo, int hi, int *out)
{
    long x;
    if (decimal(v, lo, hi, &x))
        return -1;
    *out = (int)x;
    return 0;
}

int conf_schema_number(const struct conf_key *k, const char *v, long *out)
{
    if (k->type == CONF_T_BOOL || k->type == CONF_T_FLAG)
        return parse_bool(v, out);
    for (int j = 0; k->words && k->words[j].word; j++)
        if (!strcasecmp(v, k->words[j].word)) {
            *out = k->words[j].code;
            return 0;
        }
    if (k->type != CONF_T_INT)
        return -1;
    return decimal(v, k->lo, k->hi, out);
}

/* "a, b or c" of k's listed words into buf (at its end). */
static void words_text(const struct conf_key *k, char *buf, size_t size, const char *last_sep)
{
    int n = 0, total = 0;
    for (int j = 0; k->words && k->words[j].word; j++)
        total += !k->words[j].hidden;
    for (int j = 0; k->words && k->words[j].word; j++) {
        size_t len = strlen(buf);
        if (k->words[j].hidden)
            continue;
        snprintf(buf + len, size - len, "%s%s", n == 0 ? "" : n == total - 1 ? last_sep : ", ", k->words[j].word);
        n++;
    }
}

void conf_schema_expect(const struct conf_key *k, char *buf, size_t size)
{
    size_t len;
    snprintf(buf, size, "expected ");
    switch (k->type) {
    case CONF_T_BOOL:
    case CONF_T_FLAG: snprintf(buf, size, "expected yes or no"); return;
    case CONF_T_ENUM: words_text(k, buf, size, " or "); break;
    case CONF_T_INT:
        words_text(k, buf, size, ", ");
        len = strlen(buf);
        snprintf(buf + len, size - len, "%s%s%s%ld..%ld", k->words && k->words[0].word ? " or " : "",
                 k->unit ? k->unit : "", k->unit ? " " : "", k->lo, k->hi);
        break;
    default: snprintf(buf, size, "expected %s", k->help); return;
    }
    len = strlen(buf);
    if (k->note)
        snprintf(buf + len, size - len, " (%s)", k->note);
}

/* ---- the reference ---- */

/* What a value of k looks like, for the reference. */
static void type_text(const struct conf_key *k, char *buf, size_t size)
{
    /* clang-format off */
    static const char *const names[] = {
        [CONF_T_STR] = "text", [CONF_T_PATH] = "path", [CONF_T_FILE] = "file (readable)",
        [CONF_T_SECRET] = "file", [CONF_T_USER] = "user name", [CONF_T_LISTEN] = "host:port or none",
        [CONF_T_ADDR] = "host:port", [CONF_T_ENDPOINT] = "host:port or none", [CONF_T_ALLOW] = "addresses/prefixes",
        [CONF_T_USB] = "VID:PID[:serial]", [CONF_T_BROKER] = "host[:port]", [CONF_T_SPB_ID] = "topic level",
        /* clang-format on */
    };
    buf[0] = 0;
    switch (k->type) {
    case CONF_T_BOOL:
    case CONF_T_FLAG: snprintf(buf, size, "yes/no"); break;
    case CONF_T_ENUM: words_text(k, buf, size, ", "); break;
    case CONF_T_INT: {
        size_t len;
        words_text(k, buf, size, ", ");
        len = strlen(buf);
        snprintf(buf + len, size - len, "%s%ld..%ld%s%s%s%s", buf[0] ? ", " : "", k->lo, k->hi,
                 k->unit && !strcmp(k->unit, "seconds")        ? " s"
                 : k->unit && !strcmp(k->unit, "milliseconds") ? " ms"
                 : k->unit && !strcmp(k->unit, "microseconds") ? " µs"
                                                               : "",
                 k->note ? " (" : "", k->note ? k->note : "", k->note ? ")" : "");
        break;
    }
    case CONF_T_STR:
    case CONF_T_SPB_ID: snprintf(buf, size, "%s, 1..%zu bytes", names[k->type], k->size - 1); break;
    default: snprintf(buf, size, "%s", names[k->type]); break;
    }
}

static const char *def_text(const struct conf_key *k)
{
    return k->def_doc ? k->def_doc : k->def ? k->def : "";
}

static void header_text(const struct conf_section *s, char *buf, size_t size)
{
    snprintf(buf, size, "[%s%s]", s->name, s->arg ? s->arg : "");
}

static void print_markdown(FILE *f)
{
    char hdr[64], type[160];
    for (int j = 0; j < NSECTIONS; j++) {
        const struct conf_section *s = &sections[j];
        header_text(s, hdr, sizeof hdr);
        fprintf(f, "%s### `%s`%s\n", j ? "\n" : "", hdr, s->title);
        fprintf(f, "| key | values | default | reload | meaning |\n|---|---|---|---|---|\n");
        for (int k = 0; k < s->nkeys; k++) {
            const struct conf_key *key = &s->keys[k];
            const char *d = def_text(key);
            int code = key->def && !key->def_doc;
            type_text(key, type, sizeof type);
            fprintf(f, "| `%s` | %s | %s%s%s | %s | %s |\n", key->name, type, code ? "`" : "", d, code ? "`" : "",
                    key->flags & CONF_K_RESTART ? "restart" : "yes", key->help);
        }
    }
}

/* Text for a terminal: help wrapped at 78 columns under each key. */
static void print_text(FILE *f)
{
    char hdr[64], type[160];
    for (int j = 0; j < NSECTIONS; j++) {
        const struct conf_section *s = &sections[j];
        header_text(s, hdr, sizeof hdr);
        fprintf(f, "%s%s%s\n", j ? "\n" : "", hdr, s->title);
        for (int k = 0; k < s->nkeys; k++) {
            const struct conf_key *key = &s->keys[k];
            const char *h = key->help;
            type_text(key, type, sizeof type);
            fprintf(f, "  %s = %s", key->name, type);
            if (def_text(key)[0])
                fprintf(f, "  (default: %s)", def_text(key));
            fprintf(f, "%s\n", key->flags & CONF_K_RESTART ? "  [reload: restart]" : "");
            while (*h) {
                int n = (int)strlen(h), cut = n;
                if (n > 72) {
                    cut = 72;
                    while (cut > 0 && h[cut] != ' ')
                        cut--;
                    if (cut == 0)
                        cut = 72;
                }
                fprintf(f, "      %.*s\n", cut, h);
                h += cut;
                while (*h == ' ')
                    h++;
            }
        }
    }
}

/* libFuzzer dictionary: "token" lines, escaped as its parser wants. */
static void dict_entry(FILE *f, const char *tok)
{
    fputc('"', f);
    for (const char *c = tok; *c; c++) {
        if (*c == '"' || *c == '\\')
            fprintf(f, "\\%c", *c);
        else if (*c < 0x20 || *c > 0x7e)
            fprintf(f, "\\x%02X", (unsigned char)*c);
        else
            fputc(*c, f);
    }
    fputs("\"\n", f);
}

static void print_dict(FILE *f)
{
    char hdr[80];
    for (int j = 0; j < NSECTIONS; j++) {
        const struct conf_section *s = &sections[j];
        snprintf(hdr, sizeof hdr, "[%s%s]\n", s->name, s->arg ? (!strcmp(s->arg, "ID") ? "1" : "a") : "");
        dict_entry(f, hdr);
        for (int k = 0; k < s->nkeys; k++) {
            const struct conf_key *key = &s->keys[k];
            snprintf(hdr, sizeof hdr, "%s = ", key->name);
            dict_entry(f, hdr);
            for (int w = 0; key->words && key->words[w].word; w++)
                dict_entry(f, key->words[w].word);
            if (key->type == CONF_T_INT) {
                snprintf(hdr, sizeof hdr, "%ld", key->lo);
                dict_entry(f, hdr);
                snprintf(hdr, sizeof hdr, "%ld", key->hi);
                dict_entry(f, hdr);
            }
        }
    }
    dict_entry(f, "yes");
    dict_entry(f, "no");
}

int conf_schema_print(FILE *f, const char *format)
{
    if (!strcmp(format, "text"))
        print_text(f);
    else if (!strcmp(format, "markdown"))
        print_markdown(f);
    else if (!strcmp(format, "dict"))
        print_dict(f);
    else
        return -1;
    return 0;
}
