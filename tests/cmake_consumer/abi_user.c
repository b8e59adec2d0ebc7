/* ABI guard check (make pkg-install, make cmake-consumer): calls every
 * entry point whose structs are sized by a build option (it2n.h:
 * IT2N_MAX_DEGREE, IT2N_CHORD, IT2N_BSPLINE_MAX_N; it2n_proto.h: IT2N_PROTO_WINDOW,
 * IT2N_PROTO_MAX_PAYLOAD, IT2N_PROTO_RX_REORDER). Compiled with the
 * library's options it links and exits 0; compiled with any other value it
 * must fail to link, naming each entry point with the options it asked for.
 * usage: abi_user   (prints the options it was compiled with) */
#include <stdio.h>
#include <string.h>

#include "it2n.h"
#include "it2n_inst.h"

static int sink(void *user, const uint8_t *buf, size_t len)
{
    (void)buf;
    *(size_t *)user += len;
    return 0;
}

static uint32_t clock_ms(void *user)
{
    (void)user;
    return 0;
}

static int ostream_sink(it2n_ostream *s, const uint8_t *p, size_t n)
{
    (void)s;
    (void)p;
    (void)n;
    return 0;
}

static int on_rx(void *app, uint16_t seq, const it2n_msg *msg)
{
    (void)app;
    (void)seq;
    (void)msg;
    return 0;
}

static int check(void)
{
    static it2n_dataset ds;
    static it2n_model mdl;
    static it2n_bspline_rec brec[IT2N_BSPLINE_DATA_RECS(1u, 1u, 0u)];
    it2n_bspline_data bds;
    static it2n_msg msg;
    static it2n_frame_decoder dec;
    static it2n_link link;
    static it2n_inst inst;
    static uint8_t buf[IT2N_PROTO_MAX_PAYLOAD];
    it2n_errinfo err;
    it2n_frame_hdr hdr;
    it2n_ostream os = { ostream_sink, NULL };
    it2n_link_cfg lc;
    it2n_inst_cfg ic;
    size_t sent = 0;
    int n;

    /* core: a data set and a model of the largest degree this build has */
    if (it2n_dataset_init(&ds, IT2N_MAX_DEGREE, IT2N_MAX_DEGREE,
                          IT2N_CHORD ? IT2N_F_CHORD : 0u, &err) != IT2N_OK)
        return 1;
    it2n_model_init(&mdl);
    if (mdl.solved != 0u || it2n_dataset_missing(&ds) !=
            (IT2N_MAX_DEGREE + 1u) * (IT2N_MAX_DEGREE + 1u) * IT2N_FP_COUNT)
        return 2;
    /* a B-spline data set (its init carries IT2N_BSPLINE_MAX_N) */
    if (it2n_bspline_data_init(&bds, brec, sizeof brec / sizeof brec[0], 1u, 1u, 0u, &err) != IT2N_OK ||
        it2n_bspline_data_missing(&bds) != 4u * IT2N_FP_COUNT)
        return 7;
    /* messages: pack, unpack, a golden vector */
    memset(&msg, 0, sizeof msg);
    msg.type = IT2N_MSG_COMMIT;
    msg.u.model.model = 1;
    n = it2n_msg_pack(&msg, buf, sizeof buf, NULL);
    if (n <= 0 || it2n_msg_unpack(IT2N_MSG_COMMIT, buf, (size_t)n, &msg, NULL) != IT2N_OK ||
        msg.u.model.model != 1u)
        return 3;
    if (it2n_proto_vector(0, &hdr, &msg) == NULL)
        return 4;
    it2n_frame_decoder_init(&dec);
    /* a link context: its window is the build's */
    memset(&lc, 0, sizeof lc);
    lc.out = &os;
    lc.on_rx = on_rx;
    lc.rto_ms = 100;
    if (it2n_link_init(&link, &lc) != IT2N_OK || it2n_link_window(&link) != IT2N_PROTO_WINDOW)
        return 5;
    /* the instrument API (feed mode): open sends HELLO */
    memset(&ic, 0, sizeof ic);
    ic.write = sink;
    ic.now_ms = clock_ms;
    ic.user = &sent;
    if (it2n_inst_open(&inst, &ic) != IT2N_OK || sent == 0u)
        return 6;
    return 0;
}

int main(void)
{
    int rc = check();
    printf("abi_user: degree %d, chord %d, bspline %d, window %d, payload %d, reorder %d: %s (%d)\n",
           IT2N_MAX_DEGREE, IT2N_CHORD, IT2N_BSPLINE_MAX_N, IT2N_PROTO_WINDOW, IT2N_PROTO_MAX_PAYLOAD,
           IT2N_PROTO_RX_REORDER, rc == 0 ? "ok" : "FAIL", rc);
    return rc;
}
