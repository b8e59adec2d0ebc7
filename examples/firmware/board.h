/*
 * Board support for the emulated instrument firmware: qemu mps2-an385
 * (Cortex-M3, 25 MHz), CMSDK APB UART0 with an interrupt-driven receive
 * ring buffer and polled transmit, and a 1 ms SysTick time base.
 */
#ifndef FW_BOARD_H
#define FW_BOARD_H

#include <stddef.h>
#include <stdint.h>

#define FW_SYSCLK_HZ 25000000u /* mps2-an385 system clock */
#define FW_BAUD 115200u

/* Receive ring buffer size (power of two). */
#define FW_RX_RING 2048u

void board_init(void);

/* Milliseconds since board_init (SysTick, wraps at 2^32). */
uint32_t board_now_ms(void);

/* Sleep until the next interrupt (SysTick or UART receive). */
void board_idle(void);

/* Copy up to len received bytes out of the ring; returns the count. */
size_t uart_read(uint8_t *buf, size_t len);

/* Transmit len bytes, waiting for the transmit holding register. */
void uart_write(const uint8_t *buf, size_t len);

/* Bytes the ring had to drop because it was full. */
uint32_t uart_rx_overruns(void);

#endif
