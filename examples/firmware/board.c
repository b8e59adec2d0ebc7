/* mps2-an385 board support: CMSDK UART0, SysTick, NVIC (see board.h). */
#include "board.h"

/* CMSDK APB UART0 */
#define UART0_BASE 0x40004000u
#define UART_DATA (*(volatile uint32_t *)(UART0_BASE + 0x00u))
#define UART_STATE (*(volatile uint32_t *)(UART0_BASE + 0x04u))
#define UART_CTRL (*(volatile uint32_t *)(UART0_BASE + 0x08u))
#define UART_INTCLR (*(volatile uint32_t *)(UART0_BASE + 0x0Cu))
#define UART_BAUDDIV (*(volatile uint32_t *)(UART0_BASE + 0x10u))
#define UART_STATE_TXFULL 0x1u
#define UART_STATE_RXFULL 0x2u
#define UART_CTRL_TXEN 0x1u
#define UART_CTRL_RXEN 0x2u
#define UART_CTRL_RXIE 0x8u
#define UART_INT_RX 0x2u
/* UART0 receive interrupt is external IRQ 0 on mps2-an385. */
#define UART0_RX_IRQ 0u

/* SysTick and NVIC */
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define NVIC_ISER0 (*(volatile uint32_t *)0xE000E100u)

void fw_uart0_rx_isr(void);
void fw_systick_isr(void);

static volatile uint32_t ticks;
static uint8_t rx_ring[FW_RX_RING];
static volatile uint32_t rx_head; /* written by the ISR only  */
static volatile uint32_t rx_tail; /* written by the main loop */
static volatile uint32_t rx_overruns;

void fw_systick_isr(void)
{
    ticks = ticks + 1u;
}

static void rx_drain(void)
{
    /* Clear the interrupt first: a byte that lands while the data register
     * is being drained raises it again instead of being stranded with
     * RXFULL set and no interrupt pending (the UART holds one byte). */
    UART_INTCLR = UART_INT_RX;
    while (UART_STATE & UART_STATE_RXFULL) {
        uint8_t b = (uint8_t)UART_DATA;
        uint32_t h = rx_head;
        if (h - rx_tail < FW_RX_RING) {
            rx_ring[h & (FW_RX_RING - 1u)] = b;
            rx_head = h + 1u;
        } else {
            rx_overruns = rx_overruns + 1u;
        }
    }
}

void fw_uart0_rx_isr(void)
{
    rx_drain();
}

void board_init(void)
{
    UART_BAUDDIV = FW_SYSCLK_HZ / FW_BAUD;
    UART_CTRL = UART_CTRL_TXEN | UART_CTRL_RXEN | UART_CTRL_RXIE;
    NVIC_ISER0 = 1u << UART0_RX_IRQ;
    SYST_RVR = FW_SYSCLK_HZ / 1000u - 1u;
    SYST_CVR = 0u;
    SYST_CSR = 0x7u; /* processor clock, interrupt, enable */
    __asm__ volatile("cpsie i" ::: "memory");
}

uint32_t board_now_ms(void)
{
    return ticks;
}

void board_idle(void)
{
    __asm__ volatile("wfi" ::: "memory");
}

size_t uart_read(uint8_t *buf, size_t len)
{
    size_t n = 0;
    uint32_t t = rx_tail;
    if (t == rx_head && (UART_STATE & UART_STATE_RXFULL)) {
        /* Belt and braces: a byte waiting without its interrupt. */
        __asm__ volatile("cpsid i" ::: "memory");
        rx_drain();
        __asm__ volatile("cpsie i" ::: "memory");
    }
    while (n < len && t != rx_head) {
        buf[n++] = rx_ring[t & (FW_RX_RING - 1u)];
        t++;
    }
    __asm__ volatile("" ::: "memory");
    rx_tail = t;
    return n;
}

void uart_write(const uint8_t *buf, size_t len)
{
    size_t k;
    for (k = 0; k < len; k++) {
        while (UART_STATE & UART_STATE_TXFULL) {
        }
        UART_DATA = buf[k];
    }
}

uint32_t uart_rx_overruns(void)
{
    return rx_overruns;
}
