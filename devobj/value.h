/* SPDX-License-Identifier: MIT */
/*
 * devobj/value.h - a device object's value in a PDO frame, by its CiA 301
 * data type (docs/devices.md "Values"): out of a received frame, into the
 * frame of an RPDO of the device. Pure functions.
 *
 * A value leaves here in CiA 301 encoding at its type's full size
 * (CiA 301 §7.1.4-§7.1.6, little-endian): an INTEGERn mapped with fewer
 * bits is sign-extended (CiA 301 §7.4.7.1 packs entries LSB first at their
 * mapped length), an UNSIGNEDn zero-extended, a BOOLEAN is 0 or 1, a
 * string or DOMAIN the mapped bytes. An entry whose type nobody gave is an
 * UNSIGNEDn of the mapped length rounded up to bytes (UNSIGNED8..64).
 */
#ifndef COGW_DEVOBJ_VALUE_H
#define COGW_DEVOBJ_VALUE_H

#include <stdint.h>

#include "core/pdo_layout.h"

/* The type a value of entry e is given as: `asked` (a client's co_type,
 * 0 = none), else the entry's, else the UNSIGNEDn of its bits. 0 when
 * `asked` cannot carry the mapped bits (a client's wrong type). */
uint16_t devobj_value_type(const co_pdo_layout_entry *e, uint16_t asked);

/* The value of entry e in frame[0..8) as `type` into out[8]: its length. */
uint8_t devobj_value_extract(const uint8_t frame[8], const co_pdo_layout_entry *e, uint16_t type,
			     uint8_t out[8]);

/* Put a value (CiA 301 encoding of `type`, len bytes) into the bits of e
 * in frame[0..8). Returns 0 or the abort code an SDO server would give:
 * 06070012/06070013 (length does not match the type), 06090030 (the value
 * does not fit the mapped bits). */
uint32_t devobj_value_insert(uint8_t frame[8], const co_pdo_layout_entry *e, uint16_t type,
			     const uint8_t *data, uint32_t len);

#endif /* COGW_DEVOBJ_VALUE_H */
