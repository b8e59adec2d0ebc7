/* test_usb_bulk — the USB link end to end inside one process, run under
 * umockdev-wrapper: umockdev emulates /dev/bus/usb/001/002 and this file
 * answers its usbdevfs ioctls (URB submit/reap/discard) as a bulk device
 * whose firmware is a protocol/ instrument: HELLO, CONFIGURE, PUT, COMMIT
 * go up the bulk IN endpoint, the daemon's ACKs come down bulk OUT. The
 * daemon side is the real links.c/link_usb.c/models.c/store.c on the real
 * poll loop. Then an unplug (transfers fail with ENODEV) closes the link and
 * a replug with a hotplug event reopens it. */
#include <errno.h>
#include <linux/usbdevice_fs.h>
#include <pthread.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <umockdev.h>

#include "conf.h"
#include "it2n_link.h"
#include "links.h"
#include "log.h"
#include "loop.h"
#include "models.h"
#include "store.h"

static int fails;
#define CHECK(c, ...)                                                          \
    do {                                                                       \
        if (!(c)) {                                                            \
            fprintf(stderr, "test_usb_bulk: FAIL line %d: ", __LINE__);        \
            fprintf(stderr, __VA_ARGS__);                                      \
            fputc('\n', stderr);                                               \
            fails++;                                                           \
        }                                                                      \
    } while (0)

/* ---- emulated device (ioctl handler; may run on umockdev's thread) ---- */

static pthread_mutex_t mu = PTHREAD_MUTEX_INITIALIZER;
static uint8_t to_host[65536], from_host[65536];
static size_t to_host_len, from_host_len;
static GList *flying_in;  /* UMockdevIoctlData* of submitted IN URBs */
static GList *done;       /* URBs ready to reap */
static int unplugged;

static void complete_in_locked(void)
{
    while (flying_in && (to_host_len || unplugged)) {
        UMockdevIoctlData *ud = flying_in->data;
        struct usbdevfs_urb *urb = (struct usbdevfs_urb *)ud->data;
        flying_in = g_list_delete_link(flying_in, flying_in);
        if (unplugged) {
            urb->status = -ENODEV;
            urb->actual_length = 0;
        } else {
            UMockdevIoctlData *buf = umockdev_ioctl_data_resolve(ud, offsetof(struct usbdevfs_urb, buffer),
                                                                 (gsize)urb->buffer_length, NULL);
            size_t n = to_host_len < (size_t)urb->buffer_length ? to_host_len : (size_t)urb->buffer_length;
            memcpy(buf->data, to_host, n);
            memmove(to_host, to_host + n, to_host_len - n);
            to_host_len -= n;
            urb->actual_length = (int)n;
            urb->status = 0;
            g_object_unref(buf);
        }
        done = g_list_append(done, ud);
    }
}

static gboolean on_ioctl(UMockdevIoctlBase *h, UMockdevIoctlClient *client, gpointer user)
{
    UMockdevIoctlData *arg = umockdev_ioctl_client_get_arg(client);
    gulong req = umockdev_ioctl_client_get_request(client);
    if (getenv("USB_TRACE"))
        fprintf(stderr, "ioctl %08lx\n", req);
    (void)h;
    (void)user;
    switch (req) {
    case USBDEVFS_GET_CAPABILITIES: {
        UMockdevIoctlData *d = umockdev_ioctl_data_resolve(arg, 0, sizeof(guint32), NULL);
        *(guint32 *)d->data = USBDEVFS_CAP_BULK_CONTINUATION | USBDEVFS_CAP_NO_PACKET_SIZE_LIM |
                              USBDEVFS_CAP_REAP_AFTER_DISCONNECT | USBDEVFS_CAP_ZERO_PACKET;
        g_object_unref(d);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
    }
    case USBDEVFS_CLAIMINTERFACE:
    case USBDEVFS_RELEASEINTERFACE:
    case USBDEVFS_CLEAR_HALT:
    case USBDEVFS_RESET:
    case USBDEVFS_RESETEP:
    case USBDEVFS_SETINTERFACE:
    case USBDEVFS_DISCONNECT_CLAIM:
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
    case USBDEVFS_IOCTL: /* kernel driver queries: none bound */
        umockdev_ioctl_client_complete(client, -1, ENODATA);
        return TRUE;
    case USBDEVFS_SUBMITURB: {
        UMockdevIoctlData *ud = umockdev_ioctl_data_resolve(arg, 0, sizeof(struct usbdevfs_urb), NULL);
        struct usbdevfs_urb *urb = (struct usbdevfs_urb *)ud->data;
        pthread_mutex_lock(&mu);
        if (unplugged) {
            pthread_mutex_unlock(&mu);
            g_object_unref(ud);
            umockdev_ioctl_client_complete(client, -1, ENODEV);
            return TRUE;
        }
        if (urb->type == USBDEVFS_URB_TYPE_BULK && (urb->endpoint & 0x80)) {
            flying_in = g_list_append(flying_in, ud);
            complete_in_locked();
        } else {
            if (urb->type == USBDEVFS_URB_TYPE_BULK) {
                UMockdevIoctlData *buf = umockdev_ioctl_data_resolve(ud, offsetof(struct usbdevfs_urb, buffer),
                                                                     (gsize)urb->buffer_length, NULL);
                memcpy(from_host + from_host_len, buf->data, (size_t)urb->buffer_length);
                from_host_len += (size_t)urb->buffer_length;
                g_object_unref(buf);
                urb->actual_length = urb->buffer_length;
                urb->status = 0;
            } else {
                urb->status = -EPIPE; /* control requests (string descriptors): stall */
            }
            done = g_list_append(done, ud);
        }
        pthread_mutex_unlock(&mu);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
    }
    case USBDEVFS_REAPURB:
    case USBDEVFS_REAPURBNDELAY: {
        pthread_mutex_lock(&mu);
        complete_in_locked();
        if (!done) {
            pthread_mutex_unlock(&mu);
            umockdev_ioctl_client_complete(client, -1, unplugged ? ENODEV : EAGAIN);
            return TRUE;
        }
        UMockdevIoctlData *ud = done->data;
        done = g_list_delete_link(done, done);
        pthread_mutex_unlock(&mu);
        UMockdevIoctlData *ptr = umockdev_ioctl_data_resolve(arg, 0, sizeof(gpointer), NULL);
        umockdev_ioctl_data_set_ptr(ptr, 0, ud);
        g_object_unref(ptr);
        g_object_unref(ud);
        umockdev_ioctl_client_complete(client, 0, 0);
        return TRUE;
    }
    case USBDEVFS_DISCARDURB: {
        gulong addr = (gulong) * (void **)arg->data;
        GList *l;
        pthread_mutex_lock(&mu);
        for (l = flying_in; l; l = l->next)
            if (((UMockdevIoctlData *)l->data)->client_addr == addr)
                break;
        if (l) {
            UMockdevIoctlData *ud = l->data;
            ((struct usbdevfs_urb *)ud->data)->status = -ENOENT;
            flying_in = g_list_delete_link(flying_in, l);
            done = g_list_append(done, ud);
        }
        pthread_mutex_unlock(&mu);
        umockdev_ioctl_client_complete(client, l ? 0 : -1, l ? 0 : EINVAL);
        return TRUE;
    }
    default:
        return FALSE;
    }
}

/* ---- the instrument firmware on the device side ---- */

static int dev_write(it2n_ostream *s, const uint8_t *buf, size_t len)
{
    (void)s;
    pthread_mutex_lock(&mu);
    if (to_host_len + len <= sizeof to_host) {
        memcpy(to_host + to_host_len, buf, len);
        to_host_len += len;
    }
    pthread_mutex_unlock(&mu);
    return 0;
}

static int acks, nacks;
static int dev_rx(void *app, uint16_t seq, const it2n_msg *m)
{
    (void)app;
    (void)seq;
    (void)m;
    return 0;
}

static void dev_done(void *app, uint16_t seq, uint8_t type, int code, const it2n_msg_nack *n)
{
    (void)app;
    (void)seq;
    (void)n;
    if (code == 0)
        acks++;
    else {
        nacks++;
        fprintf(stderr, "test_usb_bulk: %s NACKed %d\n", it2n_msg_name(type), code);
    }
}

static void commit_hook(void *arg)
{
    (void)arg;
    if (store_pending())
        links_release(store_commit() == 0);
}

static void pump(it2n_link *dl, unsigned ms)
{
    uint64_t end = loop_now_ms() + ms;
    while (loop_now_ms() < end) {
        uint8_t buf[4096];
        size_t n;
        loop_run_once(5);
        pthread_mutex_lock(&mu);
        n = from_host_len < sizeof buf ? from_host_len : sizeof buf;
        memcpy(buf, from_host, n);
        memmove(from_host, from_host + n, from_host_len - n);
        from_host_len -= n;
        pthread_mutex_unlock(&mu);
        if (n)
            it2n_link_input(dl, buf, n, (uint32_t)loop_now_ms());
        it2n_link_poll(dl, (uint32_t)loop_now_ms());
    }
}

static const char device_text[] =
    "P: /devices/usb1\n"
    "N: bus/usb/001/002\n"
    "E: SUBSYSTEM=usb\n"
    "E: DEVNAME=/dev/bus/usb/001/002\n"
    "E: DEVTYPE=usb_device\n"
    "E: BUSNUM=001\n"
    "E: DEVNUM=002\n"
    "A: busnum=1\\n\n"
    "A: devnum=2\\n\n"
    "A: speed=480\\n\n"
    "A: bConfigurationValue=1\\n\n"
    /* 1d50:6018, no string descriptors, interface 0: bulk IN 0x81, OUT 0x02 */
    "H: descriptors=12010002000000405 01d186000010000000109022000010100803209040000"
    "02ff0000000705810200020007050202000200\n";

int main(void)
{
    const char *pre = getenv("LD_PRELOAD");
    char dir[64], cmd[96];
    if (!pre || !strstr(pre, "umockdev-preload")) {
        fprintf(stderr, "test_usb_bulk: must run under umockdev-wrapper\n");
        return 2;
    }
    log_open(1, 0);
    UMockdevTestbed *tb = umockdev_testbed_new();
    UMockdevIoctlBase *handler = umockdev_ioctl_base_new();
    g_signal_connect(handler, "handle-ioctl", G_CALLBACK(on_ioctl), NULL);
    CHECK(umockdev_testbed_attach_ioctl(tb, "/dev/bus/usb/001/002", handler, NULL), "attach ioctl");
    char *text = g_strdup(device_text);
    /* The descriptor hex above is split for reading; drop the space. */
    char *sp = strchr(strstr(text, "descriptors="), ' ');
    memmove(sp, sp + 1, strlen(sp));
    CHECK(umockdev_testbed_add_from_string(tb, text, NULL), "add device");
    g_free(text);

    snprintf(dir, sizeof dir, "/tmp/it2nd-test-usb.%d", (int)getpid());
    models_init(2);
    struct model *md = models_add(1, 1, MODEL_BEZIER, 1, 1, IT2N_F_TYPE1);
    CHECK(store_open(dir, 0) == 0, "store");
    models_set_journal(store_append, NULL);
    models_set_journal_marks(store_jmark, store_jrewind);
    loop_add_hook(commit_hook, NULL);
    struct conf c;
    conf_default(&c);
    c.link_backoff_max = 1;
    c.nlinks = 1;
    memset(&c.link[0], 0, sizeof c.link[0]);
    snprintf(c.link[0].name, sizeof c.link[0].name, "usb0");
    c.link[0].type = CONF_LINK_USB;
    c.link[0].vid = 0x1d50;
    c.link[0].pid = 0x6018;
    links_start(&c);
    CHECK(links_up() == 1, "USB link open on the emulated device");

    /* Device firmware: HELLO, CONFIGURE 1x1 type-1, PUT 4 entries, COMMIT. */
    static it2n_link dl;
    it2n_ostream os = { dev_write, NULL };
    it2n_link_cfg cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.out = &os;
    cfg.on_rx = dev_rx;
    cfg.on_done = dev_done;
    cfg.rto_ms = 200;
    cfg.max_tries = 20;
    it2n_link_init(&dl, &cfg);
    static it2n_msg msgs[4];
    it2n_msg m;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_HELLO;
    m.u.hello.version_min = m.u.hello.version_max = IT2N_PROTO_VERSION;
    m.u.hello.max_degree = IT2N_MAX_DEGREE;
    m.u.hello.window = it2n_link_window(&dl);
    m.u.hello.caps = IT2N_CAP_INSTRUMENT;
    m.u.hello.max_payload = IT2N_PROTO_MAX_PAYLOAD;
    m.u.hello.max_models = 1;
    msgs[0] = m;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_CONFIGURE;
    m.u.configure.model = 1;
    m.u.configure.n = 1;
    m.u.configure.m = 1;
    m.u.configure.flags = IT2N_F_TYPE1;
    msgs[1] = m;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_PUT;
    m.u.put.model = 1;
    m.u.put.count = 4;
    for (unsigned k = 0; k < 4; k++) {
        it2n_put_entry *e = &m.u.put.e[k];
        e->i = (uint8_t)(k / 2);
        e->j = (uint8_t)(k % 2);
        e->fp = IT2N_FP_D;
        e->vals[IT2N_CH_X] = (it2n_val)(k / 2) * 10 * IT2N_VAL_ONE;
        e->vals[IT2N_CH_Y] = (it2n_val)(k % 2) * 10 * IT2N_VAL_ONE;
        e->vals[IT2N_CH_T] = IT2N_VAL_ONE / 4 * (it2n_val)k;
    }
    msgs[2] = m;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_COMMIT;
    m.u.model.model = 1;
    msgs[3] = m;
    /* The SYN frame travels alone: send as the window allows. */
    int next = 0;
    for (int t = 0; t < 200 && (next < 4 || it2n_link_pending(&dl)); t++) {
        while (next < 4 && it2n_link_can_send(&dl))
            CHECK(it2n_link_send(&dl, &msgs[next++], (uint32_t)loop_now_ms()) >= 0, "send %d", next);
        pump(&dl, 20);
    }
    CHECK(it2n_link_pending(&dl) == 0 && nacks == 0 && acks >= 4, "stream over bulk IN/OUT: %d ACKs, %d NACKs",
          acks, nacks);
    CHECK(md->state == IT2N_REGMAP_STATE_SOLVED, "model solved from the USB stream (state %d)", md->state);
    CHECK(it2n_dataset_value(&md->ds, 1, 1, IT2N_FP_D, IT2N_CH_T) == IT2N_VAL_ONE / 4 * 3, "data point (1,1) T");
    if (!fails)
        printf("test_usb_bulk: HELLO/CONFIGURE/PUT/COMMIT over emulated bulk endpoints, %d ACKs, model solved\n",
               acks);

    /* Unplug: transfers fail with ENODEV, the link closes. */
    pthread_mutex_lock(&mu);
    unplugged = 1;
    pthread_mutex_unlock(&mu);
    for (int t = 0; t < 100 && links_up(); t++)
        loop_run_once(10);
    CHECK(links_up() == 0, "link closed after the device failed");
    if (getenv("USB_TRACE"))
        fprintf(stderr, "stage: unplugged\n");
    /* Replug (and a hotplug event): the link comes back. */
    pthread_mutex_lock(&mu);
    unplugged = 0;
    pthread_mutex_unlock(&mu);
    umockdev_testbed_uevent(tb, "/sys/devices/usb1", "add");
    for (int t = 0; t < 300 && !links_up(); t++)
        loop_run_once(10);
    CHECK(links_up() == 1, "link reopened after replug");
    if (getenv("USB_TRACE"))
        fprintf(stderr, "stage: replugged\n");

    links_stop();
    store_close();
    models_free();
    loop_free();
    g_object_unref(handler);
    g_object_unref(tb);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    if (system(cmd) != 0)
        fails++;
    printf("test_usb_bulk: %s\n", fails ? "FAIL" : "ok");
    return fails ? 1 : 0;
}
