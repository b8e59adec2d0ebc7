/* test_usb_umockdev — the libusb link path against devices emulated by
 * umockdev (run under umockdev-wrapper): enumeration and VID:PID matching,
 * opening a matching device failing cleanly (no usbdevfs ioctl handler
 * here; test_usb_bulk.c has one and streams data), and hotplug
 * arrival reaching the daemon through its poll loop. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <umockdev.h>

#include "conf.h"
#include "link_usb.h"
#include "log.h"
#include "loop.h"

static int fails;
#define CHECK(c, ...)                                        \
    do {                                                     \
        if (!(c)) {                                          \
            fprintf(stderr, "test_usb_umockdev: FAIL line %d: ", __LINE__); \
            fprintf(stderr, __VA_ARGS__);                    \
            fputc('\n', stderr);                             \
            fails++;                                         \
        }                                                    \
    } while (0)

/* Device 1d50:6018, one configuration, interface 0 with bulk IN 0x81 and
 * bulk OUT 0x02, as the sysfs "descriptors" attribute holds them. */
static unsigned char descriptors[] = {
    0x12, 0x01, 0x00, 0x02, 0x00, 0x00, 0x00, 0x40, 0x50, 0x1d, 0x18, 0x60, 0x00, 0x01, 0x01, 0x02, 0x03, 0x01,
    0x09, 0x02, 0x20, 0x00, 0x01, 0x01, 0x00, 0x80, 0x32,
    0x09, 0x04, 0x00, 0x00, 0x02, 0xff, 0x00, 0x00, 0x00,
    0x07, 0x05, 0x81, 0x02, 0x00, 0x02, 0x00,
    0x07, 0x05, 0x02, 0x02, 0x00, 0x02, 0x00,
};

static char *add_device(UMockdevTestbed *tb, const char *name, int devnum)
{
    char devnum_s[8], devname[64], devnum_p[8];
    snprintf(devnum_s, sizeof devnum_s, "%d", devnum);
    snprintf(devnum_p, sizeof devnum_p, "%03d", devnum);
    snprintf(devname, sizeof devname, "/dev/bus/usb/001/%03d", devnum);
    char *path = umockdev_testbed_add_device(tb, "usb", name, NULL,
                                             "busnum", "1", "devnum", devnum_s, "speed", "480",
                                             "idVendor", "1d50", "idProduct", "6018", NULL,
                                             "BUSNUM", "001", "DEVNUM", devnum_p, "DEVNAME", devname,
                                             "DEVTYPE", "usb_device", "PRODUCT", "1d50/6018/100", NULL);
    umockdev_testbed_set_attribute_binary(tb, path, "descriptors", descriptors, sizeof descriptors);
    return path;
}

static int arrivals;
static void on_arrival(void *arg)
{
    (void)arg;
    arrivals++;
}

static void rx(void *arg, const uint8_t *b, size_t n)
{
    (void)arg;
    (void)b;
    (void)n;
}

static void gone(void *arg, const char *why)
{
    (void)arg;
    (void)why;
}

int main(void)
{
    const char *pre = getenv("LD_PRELOAD");
    if (!pre || !strstr(pre, "umockdev-preload")) {
        fprintf(stderr, "test_usb_umockdev: must run under umockdev-wrapper\n");
        return 2;
    }
    log_open(1, 0);
    UMockdevTestbed *tb = umockdev_testbed_new();
    char *dev1 = add_device(tb, "usb1", 2);

    CHECK(link_usb_init() == 0, "libusb init");
    struct conf_link c;
    memset(&c, 0, sizeof c);
    snprintf(c.name, sizeof c.name, "t");
    c.type = CONF_LINK_USB;
    c.vid = 0x1d50;
    c.pid = 0x6018;
    CHECK(link_usb_count(&c) == 1, "emulated 1d50:6018 enumerated: %d", link_usb_count(&c));
    struct conf_link other = c;
    other.pid = 0x6019;
    CHECK(link_usb_count(&other) == 0, "1d50:6019 must not match");
    CHECK(link_usb_open(&other, rx, gone, NULL) == NULL, "open of an absent device");
    /* Matching device: umockdev provides no usbdevfs ioctls, so open or
     * claim fails; the link must report "not usable" and not crash. */
    struct usb_link *u = link_usb_open(&c, rx, gone, NULL);
    printf("test_usb_umockdev: open of the emulated device %s (no usbdevfs ioctls in this test; test_usb_bulk emulates them)\n",
           u ? "succeeded" : "refused cleanly");
    link_usb_close(u);

    /* Hotplug: a second device arrives, the loop must see it. */
    link_usb_on_arrival(on_arrival, NULL);
    char *dev2 = add_device(tb, "usb2", 3);
    umockdev_testbed_uevent(tb, dev2, "add");
    uint64_t t0 = loop_now_ms();
    while (arrivals == 0 && loop_now_ms() - t0 < 2000)
        loop_run_once(50);
    CHECK(arrivals >= 1, "hotplug arrival not delivered through the poll loop");
    if (arrivals)
        printf("test_usb_umockdev: hotplug arrival delivered through the poll loop\n");
    CHECK(link_usb_count(&c) >= 1, "device list after the arrival: %d", link_usb_count(&c));

    link_usb_free();
    loop_free();
    g_free(dev1);
    g_free(dev2);
    g_object_unref(tb);
    printf("test_usb_umockdev: %s\n", fails ? "FAIL" : "ok");
    return fails ? 1 : 0;
}
