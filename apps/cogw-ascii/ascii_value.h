/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-ascii/ascii_value.h - the data-type keywords of CiA 309-3
 * (docs/ascii.md "Data types"): a value's text <-> its CANopen wire bytes
 * (little-endian, CiA 301 §7.1). No I/O, no global state; any thread.
 *
 * Text forms (what the gateway prints and what it accepts):
 *   b                 0 | 1 (also accepted: true, false)
 *   i8 i16 i32 i64    decimal; accepted also 0x hex, range-checked
 *   u8 u16 u32 u64    decimal; accepted also 0x hex, range-checked
 *   x8 x16 x32 x64    0x + hex digits (non-standard, as CANopenNode)
 *   r32 r64           shortest decimal that reads back to the same value
 *   t td              TIME_OF_DAY / TIME_DIFFERENCE: "<days> <ms>" (days
 *                     since 1984-01-01, ms after midnight)
 *   vs                between double quotes, a quote doubled ("a ""b"""),
 *                     NUL, CR and LF left out when printed
 *   os us d           MIME base64 (RFC 2045), one token, no line breaks
 *   hex               hex bytes (non-standard, as CANopenNode)
 */
#ifndef COGW_ASCII_VALUE_H
#define COGW_ASCII_VALUE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef enum ascii_kind {
	ASCII_K_BOOL,
	ASCII_K_INT,
	ASCII_K_UINT,
	ASCII_K_HEXINT,
	ASCII_K_REAL32,
	ASCII_K_REAL64,
	ASCII_K_TIME,
	ASCII_K_VSTRING,
	ASCII_K_BASE64,
	ASCII_K_HEXBYTES,
} ascii_kind;

typedef struct ascii_type {
	const char *keyword; /* "u32" */
	ascii_kind kind;
	uint8_t size;  /* wire bytes; 0 = any length */
	bool standard; /* a CiA 309-3 keyword (x*, hex are not) */
} ascii_type;

/* The keyword's type, or NULL. Any case ("U32" is u32), as the 309-3
 * tools take them. */
const ascii_type *ascii_type_find(const char *keyword, size_t len);
/* All types, ending with keyword NULL (help text, conformance tests). */
extern const ascii_type ascii_types[];

/* Value text (for vs: already unquoted) into wire bytes in buf[cap].
 * Returns 0, or -EINVAL (not a value of the type), -ERANGE (out of the
 * type's range), -E2BIG (more than cap bytes). */
int ascii_value_encode(const ascii_type *t, const char *text, size_t text_len, uint8_t *buf,
		       size_t cap, size_t *len);

/* Text of wire bytes into out[cap] (NUL-terminated). Returns the length,
 * -EBADMSG if len does not fit the type (the device sent a value of
 * another size), or -E2BIG if cap is too small. ascii_value_text_max
 * tells the cap that always suffices. */
long ascii_value_format(const ascii_type *t, const uint8_t *data, size_t len, char *out,
			size_t cap);
size_t ascii_value_text_max(const ascii_type *t, size_t len);

/* A decimal or 0x-hex unsigned number filling text[0..n) exactly:
 * 0, -EINVAL (not a number), -ERANGE (beyond 2^64-1). */
int ascii_number(const char *text, size_t n, uint64_t *out);

/* RFC 2045 base64 (no line breaks). decode: -EINVAL on a bad character or
 * padding, -E2BIG beyond cap. */
size_t ascii_base64_encode(const uint8_t *data, size_t len, char *out);
int ascii_base64_decode(const char *text, size_t text_len, uint8_t *buf, size_t cap, size_t *len);

#endif /* COGW_ASCII_VALUE_H */
