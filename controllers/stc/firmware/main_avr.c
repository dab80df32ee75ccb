/* The firmware on an AVR microcontroller (the Arduino Uno's ATmega328P): the protocol on
 * USART0, polled. At start the free RAM between the static data and the stack is painted with
 * a pattern; STATS reports how deep the stack has reached into it (its high-water mark). */
#include <avr/io.h>
#include <stdint.h>

#include "stc_link.h"

#ifndef F_CPU
#define F_CPU 16000000UL
#endif
#define BAUD 115200UL
/* double speed (U2X): the divisor's rounding error at 115200 baud is 2.1 % instead of 3.5 % */
#define UBRR_VALUE ((F_CPU + 4UL * BAUD) / (8UL * BAUD) - 1UL)
#define PAINT 0xC5u
/* bytes below the stack pointer at painting time left unpainted (the painter's own frame) */
#define PAINT_MARGIN 16u

extern uint8_t __heap_start; /* the end of .data and .bss (the linker script's symbol) */

static void paint_stack(void)
{
    uint8_t *p = &__heap_start;
    uint8_t *top = (uint8_t *)SP - PAINT_MARGIN;
    while (p < top)
        *p++ = PAINT;
}

uint16_t stc_platform_stack_bytes(void)
{
    const uint8_t *p = &__heap_start;
    while (p <= (const uint8_t *)RAMEND && *p == PAINT)
        p++;
    return (uint16_t)((const uint8_t *)RAMEND + 1 - p);
}

void stc_platform_put(uint8_t byte)
{
    while (!(UCSR0A & (1u << UDRE0)))
        ;
    UDR0 = byte;
}

int main(void)
{
    paint_stack();
    UBRR0H = (uint8_t)(UBRR_VALUE >> 8);
    UBRR0L = (uint8_t)UBRR_VALUE;
    UCSR0A = (uint8_t)(1u << U2X0);
    UCSR0B = (uint8_t)((1u << RXEN0) | (1u << TXEN0));
    UCSR0C = (uint8_t)((1u << UCSZ01) | (1u << UCSZ00)); /* 8 data bits, no parity, 1 stop bit */
    stc_link_init();
    for (;;) {
        while (!(UCSR0A & (1u << RXC0)))
            ;
        stc_link_feed(UDR0);
    }
}
