/* SPDX-License-Identifier: MIT */
/*
 * core/od.h - the object dictionary (CiA 301 §7.4).
 *
 * Contract
 * - An OD is a set of entries keyed by (index, sub-index). Each entry carries
 *   its data type, object code, access flags, current value, default value,
 *   optional limits and optional hooks.
 * - Values are kept in CANopen wire format (little-endian bytes), so SDO and
 *   PDO copy them with memcpy and the typed helpers below do the conversion.
 * - Numeric values (<= 8 bytes) live inside the entry. Strings and domains
 *   own a buffer of max_size bytes allocated when the entry is added; a write
 *   changes the current length (size) up to max_size. No allocation happens
 *   on a per-frame path.
 * - Lookup is a binary search over a sorted array of entry pointers:
 *   O(log n). Entry pointers are stable for the lifetime of the OD (adding
 *   objects moves only the pointer array), so services may keep them.
 * - Objects may be added at any time (the JSON configuration creates them).
 * - Only the thread that owns the line (and its core instance) may call
 *   these functions; nothing here locks.
 * - Functions return 0 or a negative errno. Protocol outcomes (SDO abort
 *   codes, uint32_t) are data: they are returned through hook results or
 *   out-parameters, never as errno.
 */
#ifndef COGW_CORE_OD_H
#define COGW_CORE_OD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* CiA 301 basic data types; the value is the data type index (0001h..). */
typedef enum co_type {
	CO_T_BOOLEAN = 0x01,
	CO_T_INTEGER8 = 0x02,
	CO_T_INTEGER16 = 0x03,
	CO_T_INTEGER32 = 0x04,
	CO_T_UNSIGNED8 = 0x05,
	CO_T_UNSIGNED16 = 0x06,
	CO_T_UNSIGNED32 = 0x07,
	CO_T_REAL32 = 0x08,
	CO_T_VISIBLE_STRING = 0x09,
	CO_T_OCTET_STRING = 0x0A,
	CO_T_UNICODE_STRING = 0x0B,
	CO_T_TIME_OF_DAY = 0x0C,
	CO_T_TIME_DIFFERENCE = 0x0D,
	CO_T_DOMAIN = 0x0F,
	CO_T_INTEGER24 = 0x10,
	CO_T_REAL64 = 0x11,
	CO_T_INTEGER40 = 0x12,
	CO_T_INTEGER48 = 0x13,
	CO_T_INTEGER56 = 0x14,
	CO_T_INTEGER64 = 0x15,
	CO_T_UNSIGNED24 = 0x16,
	CO_T_UNSIGNED40 = 0x18,
	CO_T_UNSIGNED48 = 0x19,
	CO_T_UNSIGNED56 = 0x1A,
	CO_T_UNSIGNED64 = 0x1B,
} co_type;

/* "UNSIGNED32", "VISIBLE_STRING", ...; "?" for unknown values. */
const char *co_type_to_string(co_type t);
/* Fixed size in bytes (BOOLEAN = 1, TIME_OF_DAY = 6, ...); 0 for the
 * variable-length types (strings, DOMAIN) and unknown types. */
uint32_t co_type_size(co_type t);
bool co_type_is_valid(co_type t);
bool co_type_is_variable(co_type t); /* strings and DOMAIN */
bool co_type_is_signed(co_type t);   /* INTEGERxx */
bool co_type_is_real(co_type t);     /* REAL32/REAL64 */

/* CiA 301 object codes. */
typedef enum co_obj_code {
	CO_OBJ_NULL = 0x0,
	CO_OBJ_DOMAIN = 0x2,
	CO_OBJ_DEFTYPE = 0x5,
	CO_OBJ_DEFSTRUCT = 0x6,
	CO_OBJ_VAR = 0x7,
	CO_OBJ_ARRAY = 0x8,
	CO_OBJ_RECORD = 0x9,
} co_obj_code;

const char *co_obj_code_to_string(co_obj_code c);

/* Access and attribute flags (co_od_entry.access). */
enum co_access {
	CO_ACC_READ = 1u << 0,    /* readable over SDO */
	CO_ACC_WRITE = 1u << 1,   /* writable over SDO */
	CO_ACC_CONST = 1u << 2,   /* value never changes (implies read-only) */
	CO_ACC_RPDO = 1u << 3,    /* may be mapped into an RPDO ("rww") */
	CO_ACC_TPDO = 1u << 4,    /* may be mapped into a TPDO ("rwr") */
	CO_ACC_PERSIST = 1u << 5, /* included in store parameters (1010h) */

	CO_ACC_RO = CO_ACC_READ,
	CO_ACC_WO = CO_ACC_WRITE,
	CO_ACC_RW = CO_ACC_READ | CO_ACC_WRITE,
	CO_ACC_CO = CO_ACC_READ | CO_ACC_CONST,
	CO_ACC_RWW = CO_ACC_RW | CO_ACC_RPDO,
	CO_ACC_RWR = CO_ACC_RW | CO_ACC_TPDO,
};

/* Where an access comes from; hooks get it to decide what to check. */
typedef enum co_od_origin {
	CO_OD_ORIGIN_LOCAL = 0, /* application or another core service */
	CO_OD_ORIGIN_SDO,       /* SDO server (remote client) */
	CO_OD_ORIGIN_PDO,       /* RPDO reception */
	CO_OD_ORIGIN_RESET,     /* reset to defaults / restore */
} co_od_origin;

const char *co_od_origin_to_string(co_od_origin o);

/*
 * Hook result meaning "I will answer later". Returned by a read or
 * check_write hook during an SDO access; the SDO server then waits (its
 * per-frame timeout still runs) until sdo_server_continue() supplies the
 * outcome. 0xFFFFFFFF is not a CiA 301 abort code, so it cannot collide.
 */
#define CO_OD_DEFERRED 0xFFFFFFFFu

typedef struct co_od co_od;
typedef struct co_od_entry co_od_entry;

/* Context of one access, handed to hooks. */
typedef struct co_od_access {
	co_od_origin origin;
	uint8_t channel;     /* SDO server channel (0-based) for ORIGIN_SDO */
	const uint8_t *data; /* check_write: new value (wire format); NULL when
	                      * the value is streamed in place (large domains,
	                      * see sdo_server.h) and only size is known */
	uint32_t size;       /* check_write/after_write: length of the new value
	                      * (the indicated size for streamed writes) */
} co_od_access;

/*
 * Hooks. All optional; ctx is the pointer given to co_od_set_hooks().
 * - check_write: before a value is stored. Return 0 to accept, a CiA abort
 *   code to refuse (the value stays unchanged), or CO_OD_DEFERRED (SDO only).
 * - after_write: after the value has been stored. Cannot refuse.
 * - read: before a value is read over SDO (or by a TPDO, at the PDO module's
 *   choice). May refresh the value with co_od_entry_set_*(); return 0, an
 *   abort code, or CO_OD_DEFERRED (SDO only).
 * - check_streamed: an SDO download streamed in place (sdo_server.h) has
 *   all its data: a->data = e->data, a->size = its length, not yet
 *   committed (e->size is the old one). Return 0, an abort code or
 *   CO_OD_DEFERRED, as check_write. Without it an in-place download is
 *   checked only at its initiate. A refusal cannot undo the bytes already
 *   in e->data: an entry whose value must survive a refusal is small
 *   enough to be staged, or its daemon copy is scratch (a served object,
 *   docs/application.md).
 */
typedef struct co_od_hooks {
	uint32_t (*check_write)(void *ctx, co_od_entry *e, const co_od_access *a);
	void (*after_write)(void *ctx, co_od_entry *e, const co_od_access *a);
	uint32_t (*read)(void *ctx, co_od_entry *e, const co_od_access *a);
	uint32_t (*check_streamed)(void *ctx, co_od_entry *e, const co_od_access *a);
} co_od_hooks;

/*
 * One sub-index. Fields are readable by all core modules; change them only
 * through the functions below.
 */
struct co_od_entry {
	uint16_t index;
	uint8_t sub;
	uint8_t obj_code; /* co_obj_code of the object this sub belongs to */
	uint8_t type;     /* co_type */
	uint8_t has_limits;
	uint16_t access;   /* enum co_access */
	uint32_t size;     /* current length in bytes */
	uint32_t max_size; /* capacity (== size for numeric types) */
	uint8_t *data;     /* -> val for numerics, owned buffer otherwise */
	uint8_t val[8];    /* numeric storage, wire format */
	uint8_t def[8];    /* numeric default, wire format */
	uint8_t min[8];    /* numeric limits, wire format (if has_limits) */
	uint8_t max[8];
	uint8_t *def_data; /* variable types: owned default value */
	uint32_t def_size;
	const co_od_hooks *hooks;
	void *hook_ctx;
	char *name; /* owned copy, may be NULL */
};

/* Everything needed to add one entry. */
typedef struct co_od_desc {
	uint16_t index;
	uint8_t sub;
	uint8_t obj_code;  /* CO_OBJ_VAR if 0 */
	uint8_t type;      /* co_type */
	uint16_t access;   /* enum co_access */
	uint32_t max_size; /* variable types: capacity; ignored for numerics */
	const void *def;   /* default in wire format, NULL = zero / empty */
	uint32_t def_size; /* bytes at def (numerics: must equal type size) */
	const void *min;   /* numeric limits in wire format, NULL = none */
	const void *max;
	const char *name; /* copied, may be NULL */
} co_od_desc;

/* ---- lifetime ---------------------------------------------------------- */

/* Create an empty OD with room for capacity_hint entries (it grows). */
int co_od_create(co_od **out, size_t capacity_hint);
void co_od_destroy(co_od *od); /* accepts NULL */

/* ---- building ---------------------------------------------------------- */

/* Add one entry. -EEXIST if (index, sub) exists, -EINVAL for a bad
 * descriptor (unknown type, default too long, ...), -ENOMEM. The value is
 * set to the default. *out (optional) receives the stable entry pointer. */
int co_od_add(co_od *od, const co_od_desc *d, co_od_entry **out);

/* Convenience: numeric VAR/sub with a default given as the raw bit pattern
 * (two's complement for signed types, IEEE 754 bits for reals). */
int co_od_add_num(co_od *od, uint16_t index, uint8_t sub, co_type type, uint16_t access,
		  uint64_t def_bits, co_od_entry **out);
/* Like co_od_add_num, for building default layouts: an (index, sub) that
 * exists already is left as it is and counts as success. A new entry gets
 * obj_code unless that is 0 (VAR). 0, -EINVAL or -ENOMEM. */
int co_od_ensure_num(co_od *od, uint16_t index, uint8_t sub, co_type type, uint16_t access,
		     uint64_t def_bits, uint8_t obj_code);
/* Convenience: string or domain with capacity max_size and a default. */
int co_od_add_bytes(co_od *od, uint16_t index, uint8_t sub, co_type type, uint16_t access,
		    uint32_t max_size, const void *def, uint32_t def_size, co_od_entry **out);
/* Convenience: an ARRAY (obj_code ARRAY): sub0 = n (UNSIGNED8, ro) and
 * subs 1..n of a numeric type, all with default def_bits. */
int co_od_add_array(co_od *od, uint16_t index, co_type type, uint8_t n, uint16_t access,
		    uint64_t def_bits);

/* Limits for a numeric entry, as raw bit patterns of the entry's type.
 * Checked on SDO writes (and co_od_write); -EINVAL for non-numerics. */
int co_od_entry_set_limits(co_od_entry *e, uint64_t min_bits, uint64_t max_bits);

/* Attach hooks (NULL to detach). One hook set per entry: the service that
 * owns the object installs them; the application listens to events. */
int co_od_set_hooks(co_od *od, uint16_t index, uint8_t sub, const co_od_hooks *hooks, void *ctx);
void co_od_entry_set_hooks(co_od_entry *e, const co_od_hooks *hooks, void *ctx);

/* ---- lookup ------------------------------------------------------------ */

co_od_entry *co_od_find(const co_od *od, uint16_t index, uint8_t sub);
/* Like co_od_find, but tells why not: *abort = 0x06020000 (no object) or
 * 0x06090011 (no such sub-index). */
co_od_entry *co_od_find_ex(const co_od *od, uint16_t index, uint8_t sub, uint32_t *abort);
bool co_od_has_index(const co_od *od, uint16_t index);
size_t co_od_count(const co_od *od);
/* Entries in (index, sub) order; NULL past the end. Invalidated (the
 * position, not the entry) by co_od_add. */
co_od_entry *co_od_at(const co_od *od, size_t pos);

/* ---- values: raw access without checks or hooks ------------------------ */

/* Numeric value as a raw little-endian bit pattern (zero-extended). */
uint64_t co_od_entry_raw(const co_od_entry *e);
/* Set a numeric value from a raw bit pattern (truncated to the size). */
void co_od_entry_set_raw(co_od_entry *e, uint64_t bits);
/* Replace the bytes of any entry; -EMSGSIZE if len > max_size, -EINVAL if
 * a numeric entry gets a len other than its size. */
int co_od_entry_set_bytes(co_od_entry *e, const void *buf, uint32_t len);

/* Typed helpers by (index, sub). get: -ENOENT if missing, -EINVAL if the
 * entry is not numeric or wider than the C type; signed types are
 * sign-extended. set: -ERANGE if the value does not fit the entry. No
 * hooks run: these are the application's and the services' own accesses. */
int co_od_get_u8(const co_od *od, uint16_t index, uint8_t sub, uint8_t *v);
int co_od_get_u16(const co_od *od, uint16_t index, uint8_t sub, uint16_t *v);
int co_od_get_u32(const co_od *od, uint16_t index, uint8_t sub, uint32_t *v);
int co_od_get_u64(const co_od *od, uint16_t index, uint8_t sub, uint64_t *v);
int co_od_get_i8(const co_od *od, uint16_t index, uint8_t sub, int8_t *v);
int co_od_get_i16(const co_od *od, uint16_t index, uint8_t sub, int16_t *v);
int co_od_get_i32(const co_od *od, uint16_t index, uint8_t sub, int32_t *v);
int co_od_get_i64(const co_od *od, uint16_t index, uint8_t sub, int64_t *v);
int co_od_get_r32(const co_od *od, uint16_t index, uint8_t sub, float *v);
int co_od_get_r64(const co_od *od, uint16_t index, uint8_t sub, double *v);
int co_od_set_u8(co_od *od, uint16_t index, uint8_t sub, uint8_t v);
int co_od_set_u16(co_od *od, uint16_t index, uint8_t sub, uint16_t v);
int co_od_set_u32(co_od *od, uint16_t index, uint8_t sub, uint32_t v);
int co_od_set_u64(co_od *od, uint16_t index, uint8_t sub, uint64_t v);
int co_od_set_i8(co_od *od, uint16_t index, uint8_t sub, int8_t v);
int co_od_set_i16(co_od *od, uint16_t index, uint8_t sub, int16_t v);
int co_od_set_i32(co_od *od, uint16_t index, uint8_t sub, int32_t v);
int co_od_set_i64(co_od *od, uint16_t index, uint8_t sub, int64_t v);
int co_od_set_r32(co_od *od, uint16_t index, uint8_t sub, float v);
int co_od_set_r64(co_od *od, uint16_t index, uint8_t sub, double v);
/* Copy the value out: *len = current size; -EMSGSIZE if cap is too small
 * (nothing copied, *len still set). */
int co_od_get_bytes(const co_od *od, uint16_t index, uint8_t sub, void *buf, uint32_t cap,
		    uint32_t *len);
int co_od_set_bytes(co_od *od, uint16_t index, uint8_t sub, const void *buf, uint32_t len);

/* ---- checked writes (what SDO and RPDO use) ---------------------------- */

/* Validate a new value: length against type/max size (0x06070010/12/13),
 * BOOLEAN 0/1 (0x06090030), limits (0x06090031/32). Does not check the
 * access flags (the caller knows its own rules) and runs no hook.
 * Returns 0 or an abort code. */
uint32_t co_od_check_value(const co_od_entry *e, const uint8_t *data, uint32_t len);
/* check_value, then the check_write hook, then store, then after_write.
 * Returns 0, an abort code (value unchanged) or CO_OD_DEFERRED (value
 * unchanged; the caller must later call co_od_commit()). */
uint32_t co_od_write(co_od_entry *e, const uint8_t *data, uint32_t len, const co_od_access *a);
/* Store a value that has already passed its checks, then run after_write. */
void co_od_commit(co_od_entry *e, const uint8_t *data, uint32_t len, const co_od_access *a);

/* ---- defaults ---------------------------------------------------------- */

/* Set every entry with first <= index <= last back to its default. No
 * hooks run; the services re-read their objects after a reset.
 * Reset communication = 1000h..1FFFh, reset application = 0000h..FFFFh. */
void co_od_reset_range(co_od *od, uint16_t first, uint16_t last);
void co_od_entry_reset(co_od_entry *e);
/* Change the default of a numeric entry (raw bit pattern); the current
 * value is not touched. */
void co_od_entry_set_default_raw(co_od_entry *e, uint64_t bits);
/* Change the default of any entry to len bytes (wire format); the current
 * value is not touched. Numerics: len must equal the size (-EINVAL).
 * Strings/domains: -EMSGSIZE if len > max_size, -ENOMEM (allocates: call
 * at OD build time, e.g. when the configuration sets initial values). */
int co_od_entry_set_default_bytes(co_od_entry *e, const void *buf, uint32_t len);

#endif /* COGW_CORE_OD_H */
