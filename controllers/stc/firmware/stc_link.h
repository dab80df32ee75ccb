/* The serial protocol's controller side in portable C99 (the Python side and the frame layout:
 * stcvision.controllers.stc.link; docs: "Serial protocol"). A frame:
 *   0xA5 | version | type | seq | length | payload | CRC-16/CCITT-FALSE (high byte first)
 * over version..payload. Bytes are fed one at a time (stc_link_feed); a whole, checked request
 * is answered through the platform's byte writer. */
#ifndef STC_LINK_H
#define STC_LINK_H

#include <stdint.h>

#define STC_LINK_SYNC 0xA5u
#define STC_LINK_VERSION 1u
#define STC_LINK_MAX_PAYLOAD 64u
#define STC_LINK_REPLY 0x80u
#define STC_LINK_NAK 0x7Fu

/* the requests this side answers (the robot's own are answered by the robot) */
#define STC_REQ_HELLO 0x01u
#define STC_REQ_STEP 0x02u
#define STC_REQ_STEP_FROM 0x03u
#define STC_REQ_RESET 0x04u
#define STC_REQ_STATS 0x05u

/* NAK codes */
#define STC_NAK_CHECKSUM 1u
#define STC_NAK_UNKNOWN 2u
#define STC_NAK_LENGTH 3u
#define STC_NAK_VERSION 4u

/* the platform's glue: write one byte to the line; the stack's deepest use so far (bytes, 0
 * where it is not measured) */
void stc_platform_put(uint8_t byte);
uint16_t stc_platform_stack_bytes(void);

/* start: the controller in its initial state, waiting for a frame */
void stc_link_init(void);
/* one byte from the line */
void stc_link_feed(uint8_t byte);

#endif
