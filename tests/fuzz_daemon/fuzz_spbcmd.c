/* Fuzz target "spbcmd": arbitrary bytes as the payload of a Sparkplug NCMD
 * (what any client allowed to publish on the node's NCMD topic sends),
 * decoded by spb_payload_cmd_parse (protobuf-c code generated from daemon/spb.proto).
 * Invariants (abort on violation):
 *  - spb_payload_cmd_each (DCMD) decodes the same bytes all or nothing: every
 *    metric it hands over has a known value kind, a terminated name, a
 *    Boolean 0/1, a 32-bit int_value; the same count as spb_payload_cmd_parse;
 *  - the NCMD decoder returns 0 or -1; -1 comes with a reason, 0 with
 *    rebirth 0 or 1 and a metric count >= 0;
 *  - round trip: a payload built by the daemon's encoder (spb_pl_*) from
 *    the input (a Rebirth true/false by name or by alias, and a String
 *    metric holding input bytes) decodes to the same Rebirth request.
 *  - the same bytes as a STATE payload of the primary host (spb_payload_state_parse,
 *    JSON): 0 with online 0/1, or -1 with a reason; a STATE built from the
 *    input's first bytes (online, timestamp) parses back to the same values.
 * Built as a libFuzzer target (make fuzzd-fuzz) and, with fuzz_main.c, as a
 * plain corpus run under make test. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fake_env.h"
#include "spb_payload.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define REBIRTH_ALIAS 2u

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    return 0;
}

static void round_trip(const uint8_t *data, size_t size)
{
    struct spb_payload *pl = spb_payload_new(2);
    struct spb_payload_val v;
    struct spb_payload_cmd cmd;
    char text[64], why[128];
    uint8_t *buf;
    size_t len, n = size < sizeof text - 1 ? size : sizeof text - 1;
    int want = size && (data[0] & 1), by_alias = size && (data[0] & 2);
    fuzz_check(pl != NULL, "builder");
    memset(&v, 0, sizeof v);
    for (size_t k = 0; k < n; k++)
        text[k] = data[k] ? (char)data[k] : '.';
    text[n] = 0;
    v.s = text;
    fuzz_check(spb_payload_add(pl, "Other", 0, SPB_PAYLOAD_STRING, 1, &v) == 0, "add string");
    v.s = NULL;
    v.u = (uint64_t)want;
    fuzz_check(spb_payload_add(pl, by_alias ? NULL : "Node Control/Rebirth", by_alias ? REBIRTH_ALIAS : 0, SPB_PAYLOAD_BOOLEAN,
                          2, &v) == 1, "add rebirth");
    fuzz_check(spb_payload_pack(pl, 3, -1, &buf, &len) == 0, "pack");
    fuzz_check(spb_payload_cmd_parse(buf, len, REBIRTH_ALIAS, &cmd, why, sizeof why) == 0, "own payload decodes");
    fuzz_check(cmd.rebirth == want && cmd.nmetrics == 2, "round trip: the same Rebirth request");
    free(buf);
    spb_payload_free(pl);
}

struct each_ctx {
    int n;
};

/* Every metric the DCMD decoder hands over is well formed. */
static void each_metric(void *ctx, const struct spb_payload_in *m)
{
    struct each_ctx *c = ctx;
    c->n++;
    fuzz_check(m->kind >= SPB_PAYLOAD_IN_NONE && m->kind <= SPB_PAYLOAD_IN_OTHER, "value kind");
    fuzz_check(!m->name || strlen(m->name) < (1u << 17), "name terminated");
    fuzz_check(m->kind != SPB_PAYLOAD_IN_BOOL || m->u <= 1, "boolean 0 or 1");
    fuzz_check(m->kind != SPB_PAYLOAD_IN_INT || m->u <= UINT32_MAX, "int_value is 32 bits");
}

static void state_check(const uint8_t *data, size_t size)
{
    char why[128], json[96];
    int online = -1, rc;
    uint64_t ts = 0, want = 0;
    why[0] = 0;
    rc = spb_payload_state_parse(data, size, &online, &ts, why, sizeof why);
    fuzz_check(rc == 0 || (rc == -1 && why[0]), "STATE: 0 or -1 with a reason");
    fuzz_check(rc != 0 || online == 0 || online == 1, "STATE: online is a Boolean");
    for (size_t k = 1; k < size && k < 9; k++)
        want = want << 8 | data[k];
    snprintf(json, sizeof json, "{\"timestamp\" : %llu,\"online\":%s }", (unsigned long long)want,
             size && (data[0] & 1) ? "true" : "false");
    fuzz_check(spb_payload_state_parse((const uint8_t *)json, strlen(json), &online, &ts, why, sizeof why) == 0 && ts == want &&
                   online == (size && (data[0] & 1)),
               "STATE round trip");
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    struct spb_payload_cmd cmd;
    struct each_ctx ec = { 0 };
    char why[128];
    int rc, rc2;
    why[0] = 0;
    rc = spb_payload_cmd_parse(data, size, REBIRTH_ALIAS, &cmd, why, sizeof why);
    fuzz_check(rc == 0 || rc == -1, "return value");
    if (rc)
        fuzz_check(why[0] != 0 && memchr(why, 0, sizeof why) != NULL, "a refusal says why");
    else
        fuzz_check((cmd.rebirth == 0 || cmd.rebirth == 1) && cmd.nmetrics >= 0, "decoded command");
    why[0] = 0;
    rc2 = spb_payload_cmd_each(data, size, each_metric, &ec, why, sizeof why);
    fuzz_check(rc2 == 0 || (rc2 == -1 && why[0] && ec.n == 0), "DCMD decoder: all or nothing, with a reason");
    fuzz_check(rc2 != 0 || rc != 0 || ec.n == cmd.nmetrics, "both decoders see the same metrics");
    round_trip(data, size);
    state_check(data, size);
    return 0;
}
