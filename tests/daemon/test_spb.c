/* test_spb — the [sparkplug] key parser (spb_conf.c) and the payload
 * builder (spb_payload.c) in isolation: broker address forms, id rules,
 * the password file, required keys; payloads decoded back with the
 * protoc-c code (field by field: names, aliases, datatypes, signed values
 * as 32-bit two's complement, is_null, properties, seq absent for NDEATH);
 * the NCMD decoder's answers. The wire against a real broker and an
 * independent decoder: tests/sparkplug/spb_test.py. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>
#include <unistd.h>

#include "conf.h"
#include "spb.pb-c.h"
#include "spb_conf.h"
#include "spb_payload.h"

static int key(struct spb_conf *s, const char *k, const char *v)
{
    char err[256];
    return conf_key(s, "sparkplug", k, v, 7, err, sizeof err);
}

static void test_broker_forms(void **state)
{
    struct spb_conf s;
    (void)state;
    spb_conf_default(&s);
    assert_int_equal(key(&s, "broker", "10.0.0.5:8883"), 0);
    assert_string_equal(s.host, "10.0.0.5");
    assert_int_equal(s.port, 8883);
    assert_int_equal(key(&s, "broker", "[::1]:1884"), 0);
    assert_string_equal(s.host, "::1");
    assert_int_equal(s.port, 1884);
    assert_int_equal(key(&s, "broker", "broker.plant"), 0);
    assert_string_equal(s.host, "broker.plant");
    assert_int_equal(s.port, 1883);
    assert_int_equal(key(&s, "broker", "[::1]"), 0);
    assert_string_equal(s.host, "::1");
    assert_int_equal(s.port, 1883);
    assert_int_equal(key(&s, "broker", "::1:1883"), -1);    /* v6 needs [] */
    assert_int_equal(key(&s, "broker", "h:0"), -1);
    assert_int_equal(key(&s, "broker", "h:65536"), -1);
    assert_int_equal(key(&s, "broker", ":1883"), -1);
    assert_int_equal(key(&s, "broker", "[::1]x"), -1);
    assert_int_equal(key(&s, "broker", "h:12a"), -1);
}

static void test_ids_and_ranges(void **state)
{
    struct spb_conf s;
    char err[256], k[32];
    int line = 0;
    (void)state;
    spb_conf_default(&s);
    assert_int_equal(key(&s, "group_id", "plant-a"), 0);
    assert_int_equal(s.first_line, 7);
    assert_string_equal(s.first_key, "group_id");
    assert_int_equal(key(&s, "group_id", "a/b"), -1);
    assert_int_equal(key(&s, "edge_node_id", "cell+7"), -1);
    assert_int_equal(key(&s, "edge_node_id", "cell#"), -1);
    assert_int_equal(key(&s, "edge_node_id", "two words"), -1);
    assert_int_equal(key(&s, "client_id", "0123456789012345678901234567890123456789012345678901234567890123"), -1);
    assert_int_equal(key(&s, "keepalive", "4"), -1);
    assert_int_equal(key(&s, "keepalive", "3601"), -1);
    assert_int_equal(key(&s, "reconnect_max", "0"), -1);
    assert_int_equal(spb_conf_sf_max(&s), 0);  /* off without a primary host */
    assert_int_equal(key(&s, "store_forward_max", "-1"), -1);
    assert_int_equal(key(&s, "store_forward_max", "1000001"), -1);
    assert_int_equal(key(&s, "primary_host_id", "scada/1"), -1);
    assert_int_equal(key(&s, "primary_host_id", "scada-1"), 0);
    assert_int_equal(spb_conf_sf_max(&s), SPB_SF_DEFAULT);
    assert_int_equal(key(&s, "store_forward_max", "0"), 0);
    assert_int_equal(spb_conf_sf_max(&s), 0);
    assert_int_equal(key(&s, "store_forward_max", "10"), 0);
    assert_int_equal(spb_conf_sf_max(&s), 10);
    assert_int_equal(key(&s, "nonsense", "1"), -1);
    /* still missing broker and edge_node_id: named with the first key */
    assert_int_equal(spb_conf_check(&s, &line, k, sizeof k, err, sizeof err), -1);
    assert_int_equal(line, 7);
    assert_string_equal(k, "group_id");
    assert_non_null(strstr(err, "broker is required"));
    assert_int_equal(key(&s, "broker", "127.0.0.1:1883"), 0);
    assert_int_equal(spb_conf_check(&s, &line, k, sizeof k, err, sizeof err), -1);
    assert_non_null(strstr(err, "edge_node_id is required"));
    assert_int_equal(key(&s, "edge_node_id", "cell-7"), 0);
    assert_int_equal(spb_conf_check(&s, &line, k, sizeof k, err, sizeof err), 0);
}

static void test_password_file(void **state)
{
    struct spb_conf s;
    char path[64], err[256], k[32];
    int line = 0;
    FILE *f;
    (void)state;
    snprintf(path, sizeof path, "/tmp/test_spb_pw.%d", (int)getpid());
    spb_conf_default(&s);
    f = fopen(path, "w");
    assert_non_null(f);
    fputs("s3cret\r\nsecond line ignored\n", f);
    fclose(f);
    assert_int_equal(conf_key(&s, "sparkplug", "password_file", path, 9, err, sizeof err), 0);
    assert_string_equal(s.password, "s3cret");
    assert_int_equal(s.password_line, 9);
    assert_int_equal(key(&s, "broker", "h"), 0);
    assert_int_equal(key(&s, "group_id", "g"), 0);
    assert_int_equal(key(&s, "edge_node_id", "n"), 0);
    assert_int_equal(spb_conf_check(&s, &line, k, sizeof k, err, sizeof err), -1);
    assert_int_equal(line, 9);
    assert_string_equal(k, "password_file");
    assert_non_null(strstr(err, "needs username"));
    f = fopen(path, "w");
    assert_non_null(f);
    fclose(f);
    assert_int_equal(conf_key(&s, "sparkplug", "password_file", path, 9, err, sizeof err), -1);
    assert_non_null(strstr(err, "is empty"));
    unlink(path);
    assert_int_equal(conf_key(&s, "sparkplug", "password_file", path, 9, err, sizeof err), -1);
    assert_non_null(strstr(err, "cannot open"));
}

static Spb__Payload *pack_unpack(struct spb_payload *pl, int seq)
{
    uint8_t *buf;
    size_t len;
    Spb__Payload *p;
    assert_int_equal(spb_payload_pack(pl, 1700000000123u, seq, &buf, &len), 0);
    p = spb__payload__unpack(NULL, len, buf);
    free(buf);
    assert_non_null(p);
    return p;
}

static void test_payload_fields(void **state)
{
    struct spb_payload *pl = spb_payload_new(6);
    struct spb_payload_val v;
    char name[16] = "Status/x";
    Spb__Payload *p;
    (void)state;
    memset(&v, 0, sizeof v);
    v.u = (uint64_t)(int64_t)-7;  /* Int16 -7 */
    assert_int_equal(spb_payload_add(pl, name, 20008, SPB_PAYLOAD_INT16, 5, &v), 0);
    memset(name, 'X', sizeof name - 1);  /* the builder owns its copy */
    assert_int_equal(spb_payload_prop(pl, 0, "description", "last error"), 0);
    assert_int_equal(spb_payload_prop(pl, 0, "engUnit", "-"), 0);
    v.u = 0;
    v.f = 0.25f;
    assert_int_equal(spb_payload_add(pl, NULL, 20023, SPB_PAYLOAD_FLOAT, 6, &v), 1);
    v.null = 1;
    assert_int_equal(spb_payload_add(pl, NULL, 20024, SPB_PAYLOAD_FLOAT, 6, &v), 2);
    v.null = 0;
    v.u = 255;
    assert_int_equal(spb_payload_add(pl, "bdSeq", 1, SPB_PAYLOAD_INT64, 7, &v), 3);
    v.s = "it2nd 1";
    assert_int_equal(spb_payload_add(pl, "Properties/Software Version", 3, SPB_PAYLOAD_STRING, 7, &v), 4);
    p = pack_unpack(pl, 200);
    assert_true(p->has_timestamp && p->timestamp == 1700000000123u);
    assert_true(p->has_seq && p->seq == 200);
    assert_int_equal(p->n_metrics, 5);
    assert_string_equal(p->metrics[0]->name, "Status/x");
    assert_true(p->metrics[0]->has_alias && p->metrics[0]->alias == 20008);
    assert_true(p->metrics[0]->has_datatype && p->metrics[0]->datatype == 2);
    assert_int_equal(p->metrics[0]->value_case, SPB__PAYLOAD__METRIC__VALUE_INT_VALUE);
    assert_int_equal(p->metrics[0]->int_value, 0xFFFFFFF9u);  /* -7 as 32-bit two's complement */
    assert_true(p->metrics[0]->has_timestamp && p->metrics[0]->timestamp == 5);
    assert_non_null(p->metrics[0]->properties);
    assert_int_equal(p->metrics[0]->properties->n_keys, 2);
    assert_string_equal(p->metrics[0]->properties->keys[1], "engUnit");
    assert_int_equal(p->metrics[0]->properties->values[0]->type, SPB_PAYLOAD_STRING);
    assert_string_equal(p->metrics[0]->properties->values[0]->string_value, "last error");
    /* DATA: alias only, no name, no datatype */
    assert_null(p->metrics[1]->name);
    assert_false(p->metrics[1]->has_datatype);
    assert_int_equal(p->metrics[1]->value_case, SPB__PAYLOAD__METRIC__VALUE_FLOAT_VALUE);
    assert_true(p->metrics[1]->float_value == 0.25f);
    assert_true(p->metrics[2]->has_is_null && p->metrics[2]->is_null);
    assert_int_equal(p->metrics[2]->value_case, SPB__PAYLOAD__METRIC__VALUE__NOT_SET);
    assert_int_equal(p->metrics[3]->value_case, SPB__PAYLOAD__METRIC__VALUE_LONG_VALUE);
    assert_int_equal(p->metrics[3]->long_value, 255);
    assert_string_equal(p->metrics[4]->string_value, "it2nd 1");
    spb__payload__free_unpacked(p, NULL);
    spb_payload_free(pl);
    /* NDEATH: no seq; a full builder refuses more */
    pl = spb_payload_new(1);
    memset(&v, 0, sizeof v);
    assert_int_equal(spb_payload_add(pl, "bdSeq", 0, SPB_PAYLOAD_INT64, 1, &v), 0);
    assert_int_equal(spb_payload_add(pl, "more", 0, SPB_PAYLOAD_INT64, 1, &v), -1);
    p = pack_unpack(pl, -1);
    assert_false(p->has_seq);
    assert_false(p->metrics[0]->has_alias);
    spb__payload__free_unpacked(p, NULL);
    spb_payload_free(pl);
}

/* A FloatArray (Net/...): the bytes as given, copied (the caller's buffer
 * may change after spb_payload_add), datatype 30; an empty one has no bytes. */
static void test_payload_float_array(void **state)
{
    struct spb_payload *pl = spb_payload_new(2);
    struct spb_payload_val v;
    uint8_t bytes[8] = { 0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x00, 0xC0 };  /* 1.0f, -2.0f little-endian */
    Spb__Payload *p;
    (void)state;
    memset(&v, 0, sizeof v);
    v.b = bytes;
    v.nb = sizeof bytes;
    v.u = 42;
    assert_int_equal(spb_payload_add(pl, "Net/D/T", 20125, SPB_PAYLOAD_FLOATARRAY, 5, &v), 0);
    memset(bytes, 0xEE, sizeof bytes);
    v.b = NULL;
    v.nb = 0;
    assert_int_equal(spb_payload_add(pl, NULL, 20126, SPB_PAYLOAD_FLOATARRAY, 5, &v), 1);
    p = pack_unpack(pl, 1);
    assert_true(p->metrics[0]->has_datatype && p->metrics[0]->datatype == 30);
    assert_int_equal(p->metrics[0]->value_case, SPB__PAYLOAD__METRIC__VALUE_BYTES_VALUE);
    assert_int_equal(p->metrics[0]->bytes_value.len, 8);
    assert_memory_equal(p->metrics[0]->bytes_value.data,
                        ((const uint8_t[]){ 0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x00, 0xC0 }), 8);
    assert_int_equal(p->metrics[1]->value_case, SPB__PAYLOAD__METRIC__VALUE_BYTES_VALUE);
    assert_int_equal(p->metrics[1]->bytes_value.len, 0);
    spb__payload__free_unpacked(p, NULL);
    spb_payload_free(pl);
}

static void test_val_equal(void **state)
{
    struct spb_payload_val a, b;
    (void)state;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    a.f = 0.0f;
    b.f = -0.0f;
    assert_false(spb_payload_val_equal(SPB_PAYLOAD_FLOAT, &a, &b));  /* bit for bit, as the host sees it */
    b.f = 0.0f;
    assert_true(spb_payload_val_equal(SPB_PAYLOAD_FLOAT, &a, &b));
    b.null = 1;
    assert_false(spb_payload_val_equal(SPB_PAYLOAD_FLOAT, &a, &b));
    a.null = 1;
    a.f = 3.0f;
    assert_true(spb_payload_val_equal(SPB_PAYLOAD_FLOAT, &a, &b));  /* null equals null, whatever is left in f */
}

static void test_cmd_parse(void **state)
{
    struct spb_payload *pl = spb_payload_new(2);
    struct spb_payload_val v;
    struct spb_payload_cmd cmd;
    char why[128];
    uint8_t *buf, junk[3] = { 0x12, 0x05, 0x0a };
    size_t len;
    (void)state;
    memset(&v, 0, sizeof v);
    v.u = 1;
    spb_payload_add(pl, NULL, 2, SPB_PAYLOAD_BOOLEAN, 1, &v);
    assert_int_equal(spb_payload_pack(pl, 1, -1, &buf, &len), 0);
    assert_int_equal(spb_payload_cmd_parse(buf, len, 2, &cmd, why, sizeof why), 0);
    assert_int_equal(cmd.rebirth, 1);
    assert_int_equal(spb_payload_cmd_parse(buf, len, 9, &cmd, why, sizeof why), 0);  /* another alias */
    assert_int_equal(cmd.rebirth, 0);
    assert_int_equal(cmd.nmetrics, 1);
    free(buf);
    spb_payload_free(pl);
    pl = spb_payload_new(1);
    v.u = 1;
    spb_payload_add(pl, "Node Control/Rebirth", 0, SPB_PAYLOAD_INT32, 1, &v);
    assert_int_equal(spb_payload_pack(pl, 1, -1, &buf, &len), 0);
    assert_int_equal(spb_payload_cmd_parse(buf, len, 2, &cmd, why, sizeof why), -1);
    assert_non_null(strstr(why, "Boolean"));
    free(buf);
    spb_payload_free(pl);
    assert_int_equal(spb_payload_cmd_parse(junk, sizeof junk, 2, &cmd, why, sizeof why), -1);
    assert_non_null(strstr(why, "not a Sparkplug B payload"));
}

struct seen {
    int n, rebirth_alias, floats;
    double last;
};

static void seen_metric(void *ctx, const struct spb_payload_in *m)
{
    struct seen *c = ctx;
    c->n++;
    if (!m->name && m->has_alias && m->alias == 2 && m->kind == SPB_PAYLOAD_IN_BOOL && m->u == 1)
        c->rebirth_alias++;
    if (m->kind == SPB_PAYLOAD_IN_FLOAT) {
        c->floats++;
        c->last = m->d;
    }
}

static void test_cmd_each(void **state)
{
    struct spb_payload *pl = spb_payload_new(3);
    struct spb_payload_val v;
    struct seen c;
    char why[128];
    uint8_t *buf, junk[2] = { 0x12, 0x09 };
    size_t len;
    (void)state;
    memset(&v, 0, sizeof v);
    memset(&c, 0, sizeof c);
    v.u = 1;
    spb_payload_add(pl, NULL, 2, SPB_PAYLOAD_BOOLEAN, 1, &v);
    v.f = 0.75f;
    spb_payload_add(pl, "Query/u", 0, SPB_PAYLOAD_FLOAT, 1, &v);
    v.null = 1;
    spb_payload_add(pl, "Query/w", 0, SPB_PAYLOAD_FLOAT, 1, &v);
    assert_int_equal(spb_payload_pack(pl, 1, -1, &buf, &len), 0);
    assert_int_equal(spb_payload_cmd_each(buf, len, seen_metric, &c, why, sizeof why), 0);
    assert_int_equal(c.n, 3);
    assert_int_equal(c.rebirth_alias, 1);
    assert_int_equal(c.floats, 1);  /* the null one has no value */
    assert_true(c.last == 0.75);
    free(buf);
    spb_payload_free(pl);
    memset(&c, 0, sizeof c);
    assert_int_equal(spb_payload_cmd_each(junk, sizeof junk, seen_metric, &c, why, sizeof why), -1);
    assert_int_equal(c.n, 0);  /* all or nothing */
}

/* Sparkplug 3.0 STATE payloads: what a host publishes, and what is refused. */
static void test_state_parse(void **state)
{
    static const struct {
        const char *in;
        int rc, online;
        uint64_t ts;
    } cases[] = {
        { "{\"online\": true, \"timestamp\": 1668114759262}", 0, 1, 1668114759262u },
        { " {\"timestamp\":5,\"online\":false} \n", 0, 0, 5 },
        { "{\"online\":true,\"timestamp\":7,\"extra\":{\"a\":[1,\"}\"]},\"x\":null}", 0, 1, 7 },
        { "{\"online\":true}", -1, 0, 0 },
        { "{\"timestamp\":1}", -1, 0, 0 },
        { "{\"online\":\"true\",\"timestamp\":1}", -1, 0, 0 },
        { "{\"online\":true,\"timestamp\":-1}", -1, 0, 0 },
        { "{\"online\":true,\"timestamp\":1.5}", -1, 0, 0 },
        { "{\"online\":true,\"timestamp\":99999999999999999999999}", -1, 0, 0 },
        { "{\"online\":true,\"timestamp\":1} x", -1, 0, 0 },
        { "ONLINE", -1, 0, 0 },
        { "{\"online\":true,\"timestamp\":1", -1, 0, 0 },
        { "", -1, 0, 0 },
    };
    (void)state;
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        int online = -1;
        uint64_t ts = 0;
        char why[128] = "";
        int rc = spb_payload_state_parse((const uint8_t *)cases[k].in, strlen(cases[k].in), &online, &ts, why, sizeof why);
        assert_int_equal(rc, cases[k].rc);
        if (rc == 0) {
            assert_int_equal(online, cases[k].online);
            assert_true(ts == cases[k].ts);
        } else {
            assert_true(why[0] != 0);
        }
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_broker_forms),  cmocka_unit_test(test_ids_and_ranges),
        cmocka_unit_test(test_password_file), cmocka_unit_test(test_payload_fields),
        cmocka_unit_test(test_payload_float_array),
        cmocka_unit_test(test_val_equal),     cmocka_unit_test(test_cmd_parse),
        cmocka_unit_test(test_cmd_each),      cmocka_unit_test(test_state_parse),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
