/* link_usb.c — see link_usb.h. */
#include "link_usb.h"

#include <libusb.h>
#include <stdlib.h>
#include <string.h>

#include "log.h"
#include "loop.h"

#define IN_SIZE 512

struct usb_link {
    libusb_device_handle *h;
    uint8_t ep_in, ep_out;
    struct libusb_transfer *in;
    uint8_t inbuf[IN_SIZE];
    int in_busy; /* IN transfer submitted, callback pending */
    int outs;    /* OUT transfers in flight                */
    int dead;
    const char *why; /* failure reason (static string) */
    long gone_timer;
    usb_rx_fn rx;
    usb_gone_fn gone;
    void *arg;
};

static libusb_context *ctx;
static libusb_hotplug_callback_handle hp;
static int have_hp;
static void (*arrival_fn)(void *);
static void *arrival_arg;
static long usb_timer;

static void on_usb_fd(void *arg, int fd, short revents)
{
    struct timeval zero = {0, 0};
    (void)arg;
    (void)fd;
    (void)revents;
    libusb_handle_events_timeout_completed(ctx, &zero, NULL);
}

static void fd_added(int fd, short events, void *user)
{
    (void)user;
    loop_add_fd(fd, events, on_usb_fd, NULL);
}

static void fd_removed(int fd, void *user)
{
    (void)user;
    loop_del_fd(fd);
}

/* libusb may need timeouts handled even without fd activity. */
static void on_usb_timer(void *arg)
{
    struct timeval zero = {0, 0};
    (void)arg;
    libusb_handle_events_timeout_completed(ctx, &zero, NULL);
    usb_timer = loop_add_timer(500, on_usb_timer, NULL);
}

static int LIBUSB_CALL on_hotplug(libusb_context *c, libusb_device *dev, libusb_hotplug_event ev, void *user)
{
    struct libusb_device_descriptor d;
    (void)c;
    (void)user;
    if (libusb_get_device_descriptor(dev, &d) == 0)
        log_info("usb %04x:%04x %s", d.idVendor, d.idProduct,
                 ev == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED ? "arrived" : "left");
    if (ev == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED && arrival_fn)
        arrival_fn(arrival_arg);
    /* Removal is reported through the failing transfers of the link. */
    return 0;
}

int link_usb_init(void)
{
    const struct libusb_pollfd **fds;
    if (ctx)
        return 0;
    if (libusb_init(&ctx)) {
        ctx = NULL;
        return -1;
    }
    fds = libusb_get_pollfds(ctx);
    for (int k = 0; fds && fds[k]; k++)
        fd_added(fds[k]->fd, fds[k]->events, NULL);
    libusb_free_pollfds(fds);
    libusb_set_pollfd_notifiers(ctx, fd_added, fd_removed, NULL);
    if (libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG) &&
        libusb_hotplug_register_callback(ctx, LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED | LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT, 0,
                                         LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY,
                                         on_hotplug, NULL, &hp) == 0)
        have_hp = 1;
    usb_timer = loop_add_timer(500, on_usb_timer, NULL);
    return 0;
}

void link_usb_free(void)
{
    if (!ctx)
        return;
    if (have_hp)
        libusb_hotplug_deregister_callback(ctx, hp);
    have_hp = 0;
    loop_cancel_timer(usb_timer);
    const struct libusb_pollfd **fds = libusb_get_pollfds(ctx);
    for (int k = 0; fds && fds[k]; k++)
        loop_del_fd(fds[k]->fd);
    libusb_free_pollfds(fds);
    libusb_exit(ctx);
    ctx = NULL;
}

void link_usb_on_arrival(void (*fn)(void *arg), void *arg)
{
    arrival_fn = fn;
    arrival_arg = arg;
}

int link_usb_match(const struct conf_link *c, uint16_t vid, uint16_t pid)
{
    return c->vid == vid && c->pid == pid;
}

int link_usb_count(const struct conf_link *c)
{
    libusb_device **list;
    int found = 0;
    ssize_t n;
    if (!ctx)
        return -1;
    n = libusb_get_device_list(ctx, &list);
    for (ssize_t k = 0; k < n; k++) {
        struct libusb_device_descriptor d;
        if (libusb_get_device_descriptor(list[k], &d) == 0 && link_usb_match(c, d.idVendor, d.idProduct))
            found++;
    }
    if (n >= 0)
        libusb_free_device_list(list, 1);
    return found;
}

/* Report the failure from the loop, not from inside libusb's event
 * handling: the link then closes the device, which libusb does not allow
 * from a transfer callback. */
static void report_gone(void *arg)
{
    struct usb_link *u = arg;
    u->gone_timer = 0;
    u->gone(u->arg, u->why);
}

static void fail(struct usb_link *u, const char *why)
{
    if (u->dead)
        return;
    u->dead = 1;
    u->why = why;
    u->gone_timer = loop_add_timer(0, report_gone, u);
}

static void LIBUSB_CALL in_done(struct libusb_transfer *t)
{
    struct usb_link *u = t->user_data;
    u->in_busy = 0;
    if (u->dead)
        return;
    if (t->status == LIBUSB_TRANSFER_COMPLETED || t->status == LIBUSB_TRANSFER_TIMED_OUT) {
        if (t->actual_length > 0)
            u->rx(u->arg, t->buffer, (size_t)t->actual_length);
        if (!u->dead && libusb_submit_transfer(t) == 0)
            u->in_busy = 1;
        else
            fail(u, "bulk IN resubmit failed");
        return;
    }
    fail(u, t->status == LIBUSB_TRANSFER_NO_DEVICE ? "device removed" : "bulk IN failed");
}

static void LIBUSB_CALL out_done(struct libusb_transfer *t)
{
    struct usb_link *u = t->user_data;
    u->outs--;
    if (t->status != LIBUSB_TRANSFER_COMPLETED && !u->dead)
        fail(u, t->status == LIBUSB_TRANSFER_NO_DEVICE ? "device removed" : "bulk OUT failed");
    free(t->buffer);
    libusb_free_transfer(t);
}

/* First bulk IN and OUT endpoints of interface 0. */
static int find_endpoints(libusb_device *dev, uint8_t *in, uint8_t *out)
{
    struct libusb_config_descriptor *cd;
    *in = *out = 0;
    if (libusb_get_active_config_descriptor(dev, &cd))
        return -1;
    if (cd->bNumInterfaces > 0 && cd->interface[0].num_altsetting > 0) {
        const struct libusb_interface_descriptor *id = &cd->interface[0].altsetting[0];
        for (int e = 0; e < id->bNumEndpoints; e++) {
            const struct libusb_endpoint_descriptor *ep = &id->endpoint[e];
            if ((ep->bmAttributes & 3) != LIBUSB_TRANSFER_TYPE_BULK)
                continue;
            if ((ep->bEndpointAddress & LIBUSB_ENDPOINT_IN) && !*in)
                *in = ep->bEndpointAddress;
            else if (!(ep->bEndpointAddress & LIBUSB_ENDPOINT_IN) && !*out)
                *out = ep->bEndpointAddress;
        }
    }
    libusb_free_config_descriptor(cd);
    return *in && *out ? 0 : -1;
}

/* Wrap a claimed handle and start the bulk IN transfer; NULL on failure
 * (the handle is then released and closed). */
static struct usb_link *start(libusb_device_handle *h, uint8_t ein, uint8_t eout, usb_rx_fn rx, usb_gone_fn gone,
                              void *arg)
{
    struct usb_link *u = calloc(1, sizeof *u);
    struct libusb_transfer *t = libusb_alloc_transfer(0);
    if (!u || !t) {
        free(u);
        if (t)
            libusb_free_transfer(t);
        libusb_release_interface(h, 0);
        libusb_close(h);
        return NULL;
    }
    u->h = h;
    u->ep_in = ein;
    u->ep_out = eout;
    u->rx = rx;
    u->gone = gone;
    u->arg = arg;
    u->in = t;
    libusb_fill_bulk_transfer(t, h, ein, u->inbuf, IN_SIZE, in_done, u, 0);
    if (libusb_submit_transfer(t)) {
        link_usb_close(u);
        return NULL;
    }
    u->in_busy = 1;
    return u;
}

struct usb_link *link_usb_open(const struct conf_link *c, usb_rx_fn rx, usb_gone_fn gone, void *arg)
{
    libusb_device **list;
    struct usb_link *u = NULL;
    ssize_t n;
    if (!ctx)
        return NULL;
    n = libusb_get_device_list(ctx, &list);
    for (ssize_t k = 0; k < n && !u; k++) {
        struct libusb_device_descriptor d;
        libusb_device_handle *h;
        uint8_t ein, eout;
        char serial[64] = "";
        if (libusb_get_device_descriptor(list[k], &d) || !link_usb_match(c, d.idVendor, d.idProduct))
            continue;
        int rc = libusb_open(list[k], &h);
        if (rc) {
            log_warn("link %s: usb %04x:%04x: open: %s", c->name, d.idVendor, d.idProduct, libusb_strerror(rc));
            continue;
        }
        if (d.iSerialNumber)
            libusb_get_string_descriptor_ascii(h, d.iSerialNumber, (unsigned char *)serial, sizeof serial);
        if (c->serial[0] && strcmp(serial, c->serial)) {
            libusb_close(h);
            continue;
        }
        if (find_endpoints(list[k], &ein, &eout)) {
            log_warn("link %s: usb %04x:%04x has no bulk IN/OUT pair on interface 0", c->name, d.idVendor, d.idProduct);
            libusb_close(h);
            continue;
        }
        libusb_set_auto_detach_kernel_driver(h, 1);
        rc = libusb_claim_interface(h, 0);
        if (rc) {
            log_warn("link %s: usb %04x:%04x: claim interface 0: %s", c->name, d.idVendor, d.idProduct,
                     libusb_strerror(rc));
            libusb_close(h);
            continue;
        }
        u = start(h, ein, eout, rx, gone, arg);
        if (!u) {
            log_warn("link %s: usb %04x:%04x: bulk IN submit failed", c->name, d.idVendor, d.idProduct);
            break;
        }
        log_info("link %s: usb %04x:%04x serial '%s', endpoints in 0x%02x out 0x%02x", c->name, d.idVendor, d.idProduct,
                 serial, ein, eout);
    }
    if (n >= 0)
        libusb_free_device_list(list, 1);
    return u;
}

int link_usb_write(struct usb_link *u, const uint8_t *buf, size_t len)
{
    struct libusb_transfer *t;
    uint8_t *copy;
    if (!u || u->dead)
        return -1;
    t = libusb_alloc_transfer(0);
    copy = malloc(len);
    if (!t || !copy) {
        free(copy);
        if (t)
            libusb_free_transfer(t);
        return 0; /* dropped; the protocol retransmits */
    }
    memcpy(copy, buf, len);
    libusb_fill_bulk_transfer(t, u->h, u->ep_out, copy, (int)len, out_done, u, 1000);
    if (libusb_submit_transfer(t)) {
        free(copy);
        libusb_free_transfer(t);
        return -1;
    }
    u->outs++;
    return 0;
}

void link_usb_close(struct usb_link *u)
{
    struct timeval tv = {0, 10000};
    if (!u)
        return;
    u->dead = 1;
    if (u->gone_timer)
        loop_cancel_timer(u->gone_timer);
    if (u->in_busy)
        libusb_cancel_transfer(u->in);
    /* Bounded wait for the cancelled transfers' callbacks. */
    for (int k = 0; k < 100 && (u->in_busy || u->outs > 0); k++)
        libusb_handle_events_timeout_completed(ctx, &tv, NULL);
    if (u->in && !u->in_busy)
        libusb_free_transfer(u->in);
    libusb_release_interface(u->h, 0);
    libusb_close(u->h);
    if (!u->in_busy && u->outs == 0)
        free(u);
    /* else: leaked deliberately rather than freed under a live callback */
}
