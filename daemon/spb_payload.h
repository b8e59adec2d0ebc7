/* spb_payload — building and reading Sparkplug B payloads (daemon/spb.proto,
 * compiled by protoc-c into spb.pb-c.c). A builder holds one payload's
 * metrics with their names, values and string properties in memory it
 * owns, so callers fill it from transient buffers and pack it once.
 * Decoding is for NCMD/DCMD: spb_payload_cmd_parse() accepts what the edge node
 * acts on and says why anything else is refused. No I/O, no globals. */
#ifndef IT2ND_SPB_PAYLOAD_H
#define IT2ND_SPB_PAYLOAD_H

#include <stddef.h>
#include <stdint.h>

/* Sparkplug datatypes used by it2nd (spec 6.4.16, spb.proto DataType). */
enum spb_payload_type {
    SPB_PAYLOAD_INT16 = 2,
    SPB_PAYLOAD_INT32 = 3,
    SPB_PAYLOAD_INT64 = 4,
    SPB_PAYLOAD_UINT16 = 6,
    SPB_PAYLOAD_UINT32 = 7,
    SPB_PAYLOAD_UINT64 = 8,
    SPB_PAYLOAD_FLOAT = 9,
    SPB_PAYLOAD_DOUBLE = 10,
    SPB_PAYLOAD_BOOLEAN = 11,
    SPB_PAYLOAD_STRING = 12,
    SPB_PAYLOAD_FLOATARRAY = 30 /* bytes_value: packed little-endian float32 (spec 6.4.17) */
};

/* A metric value. Integers in u (signed ones as their two's complement,
 * sign-extended to 64 bits), Float in f, Boolean in u (0/1), String in s
 * (not owned). FloatArray: nb bytes at b (not owned, the packed wire form)
 * and in u a hash of them that stands for the value when values are
 * compared or kept (b is only read by spb_payload_add). null: the value is
 * unknown now (is_null, no value). */
struct spb_payload_val {
    uint64_t u;
    float f;
    const char *s;
    const uint8_t *b;
    size_t nb;
    int null;
};

/* Equal as the host would see them (floats bit for bit). */
int spb_payload_val_equal(int type, const struct spb_payload_val *a, const struct spb_payload_val *b);

struct spb_payload;

/* A builder for up to cap metrics; NULL when out of memory. */
struct spb_payload *spb_payload_new(size_t cap);
void spb_payload_free(struct spb_payload *pl);

/* Append a metric. name NULL: by alias only (DATA); alias 0: none; type
 * is written when name is given (births); ts: ms UTC. Returns its index,
 * or -1 when the builder is full or out of memory. */
int spb_payload_add(struct spb_payload *pl, const char *name, uint64_t alias, int type, uint64_t ts,
                    const struct spb_payload_val *v);

/* Add a String property (key, value) to metric idx (at most 3 each). */
int spb_payload_prop(struct spb_payload *pl, int idx, const char *key, const char *value);

/* Mark every metric added so far as historical (is_historical = true:
 * store-and-forward data published after the host came back). */
void spb_payload_historical(struct spb_payload *pl);

/* Encode: payload timestamp ts, seq (< 0: none, as in NDEATH). *out is
 * malloc'ed (free it). Returns 0 or -1 (out of memory). */
int spb_payload_pack(struct spb_payload *pl, uint64_t ts, int seq, uint8_t **out, size_t *len);

/* One metric of a command (NCMD/DCMD), as decoded: by name or by alias,
 * and its value by protobuf field (kind). Valid during the callback. */
enum spb_payload_in_kind {
    SPB_PAYLOAD_IN_NONE = 0,
    SPB_PAYLOAD_IN_INT,
    SPB_PAYLOAD_IN_LONG,
    SPB_PAYLOAD_IN_FLOAT,
    SPB_PAYLOAD_IN_BOOL,
    SPB_PAYLOAD_IN_OTHER
};
struct spb_payload_in {
    const char *name; /* NULL: by alias                          */
    int has_alias;
    uint64_t alias;
    int has_datatype;
    uint32_t datatype;
    int kind;   /* enum spb_payload_in_kind; float and double: FLOAT */
    uint64_t u; /* INT (uint32 as sent), LONG, BOOL (0/1)   */
    double d;   /* FLOAT                                    */
};

/* Decode a command payload and call fn for each metric, in order.
 * Returns 0, or -1 with why (not a Sparkplug B payload). */
int spb_payload_cmd_each(const uint8_t *buf, size_t len, void (*fn)(void *ctx, const struct spb_payload_in *m),
                         void *ctx, char *why, size_t whysize);

/* What an NCMD/DCMD asks for. */
struct spb_payload_cmd {
    int rebirth;  /* "Node Control/Rebirth" = true             */
    int nmetrics; /* metrics in the payload                    */
};

/* Decode a command payload; rebirth_alias is the alias the NBIRTH gave
 * "Node Control/Rebirth" (a command may name it or use the alias).
 * Returns 0, or -1 with a reason in why (undecodable, or a Rebirth of a
 * type other than Boolean). Unknown metrics are counted, not refused. */
int spb_payload_cmd_parse(const uint8_t *buf, size_t len, uint64_t rebirth_alias, struct spb_payload_cmd *cmd,
                          char *why, size_t whysize);

/* A Sparkplug 3.0 STATE payload (spBv1.0/STATE/<host_id>, published by a
 * host application, spec 6.6): the UTF-8 JSON object {"online": true|false,
 * "timestamp": <ms>}, keys in any order, blanks allowed, other keys
 * ignored. Returns 0 with *online and *ts, or -1 with why (not such an
 * object: a missing or mistyped key, a bad number, trailing bytes). */
int spb_payload_state_parse(const uint8_t *buf, size_t len, int *online, uint64_t *ts, char *why, size_t whysize);

#endif
