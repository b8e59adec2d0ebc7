/* link_usb — raw USB instruments through libusb: the first device matching
 * VID:PID[:serial], interface 0, its first bulk IN and bulk OUT endpoints.
 * Asynchronous transfers only, with libusb's fds in the daemon's poll loop;
 * hotplug arrival and removal when libusb supports it (removal also shows
 * as a failed transfer). */
#ifndef IT2ND_LINK_USB_H
#define IT2ND_LINK_USB_H

#include <stddef.h>
#include <stdint.h>

#include "conf.h"

struct usb_link;

typedef void (*usb_rx_fn)(void *arg, const uint8_t *buf, size_t len);
typedef void (*usb_gone_fn)(void *arg, const char *why);

/* Start libusb and hook its fds into the loop. 0 or -1. link_usb_free
 * takes them out and ends libusb (after every device is closed). */
int link_usb_init(void);
void link_usb_free(void);

/* Called when any device matching a configured VID:PID arrives. */
void link_usb_on_arrival(void (*fn)(void *arg), void *arg);

/* Open the device of c (usb = VID:PID[:serial]). NULL when absent or not
 * usable (reason logged). rx gets every bulk IN chunk; gone is called once
 * when the device fails or leaves (then call link_usb_close). */
struct usb_link *link_usb_open(const struct conf_link *c, usb_rx_fn rx, usb_gone_fn gone, void *arg);

/* Queue bytes on bulk OUT (copied). 0, or -1 when the device is gone. */
int link_usb_write(struct usb_link *u, const uint8_t *buf, size_t len);

void link_usb_close(struct usb_link *u);

/* For tests: match a device descriptor against c (VID, PID; serial is
 * checked by the caller). */
int link_usb_match(const struct conf_link *c, uint16_t vid, uint16_t pid);

/* Devices currently enumerated that match c's VID:PID, or -1. */
int link_usb_count(const struct conf_link *c);

#endif
