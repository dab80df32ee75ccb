/* The firmware built for the host: the serial line is standard input and output, so the same
 * protocol code runs as a process (stcvision --fsm firmware --mcu host) without an emulator. */
#include <unistd.h>

#include "stc_link.h"

void stc_platform_put(uint8_t byte)
{
    if (write(1, &byte, 1) != 1)
        _exit(1); /* the line is gone */
}

uint16_t stc_platform_stack_bytes(void)
{
    return 0u; /* not measured on the host */
}

int main(void)
{
    uint8_t buf[64];
    ssize_t n, i;
    stc_link_init();
    while ((n = read(0, buf, sizeof buf)) > 0)
        for (i = 0; i < n; i++)
            stc_link_feed(buf[i]);
    return 0;
}
