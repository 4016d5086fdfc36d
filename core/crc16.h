/* SPDX-License-Identifier: MIT */
/*
 * core/crc16.h - CRC-16-CCITT as used by SDO block transfer (CiA 301
 * §7.2.4.3.16): polynomial x^16 + x^12 + x^5 + 1 (0x1021), initial value 0,
 * no reflection, no final XOR (also known as CRC-16/XMODEM; check value of
 * "123456789" is 0x31C3).
 */
#ifndef COGW_CORE_CRC16_H
#define COGW_CORE_CRC16_H

#include <stddef.h>
#include <stdint.h>

#define CRC16_CCITT_INIT 0x0000u

/* Continue a CRC over len more bytes; start with CRC16_CCITT_INIT. */
uint16_t crc16_ccitt(uint16_t crc, const void *data, size_t len);

#endif /* COGW_CORE_CRC16_H */
