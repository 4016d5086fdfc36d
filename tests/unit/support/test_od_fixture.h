/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/support/test_od_fixture.h - the object dictionaries the unit
 * tests share: the STI pressure transducer (etc/devices/sti-pressure.json,
 * docs/cosim.md) plus objects that exercise every abort path.
 */
#ifndef COGW_TESTS_TEST_OD_FIXTURE_H
#define COGW_TESTS_TEST_OD_FIXTURE_H

#include "core/od.h"

#define FX_DEVICE_NAME "STI-SIM pressure transducer"
#define FX_SERIAL 123456u

/* Test objects (manufacturer area). */
#define FX_IDX_WO 0x2100u      /* :0 UNSIGNED8 write-only */
#define FX_IDX_LIMITED 0x2101u /* :0 UNSIGNED16 rw, limits 10..1000 */
#define FX_IDX_BOOL 0x2102u    /* :0 BOOLEAN rw */
#define FX_IDX_SIGNED 0x2103u  /* :0 INTEGER16 rw, limits -100..100 */
#define FX_IDX_GAPS 0x2104u    /* RECORD subs 0, 1, 3 (2 missing) */
#define FX_IDX_DOMAIN 0x2200u  /* :0 DOMAIN rw, max FX_DOMAIN_MAX (in place) */
#define FX_IDX_OCTETS 0x2201u  /* :0 OCTET_STRING rw, max 1000 (staged) */
#define FX_IDX_CONST 0x2300u   /* :0 UNSIGNED32 const 0xC0FFEE */
#define FX_IDX_HOOKED 0x2400u  /* :0 UNSIGNED32 rw (tests attach hooks) */
#define FX_IDX_U64 0x2401u     /* :0 UNSIGNED64 rw */
#define FX_IDX_STR 0x2402u     /* :0 VISIBLE_STRING rw, max 64 */
#define FX_DOMAIN_MAX (200u * 1024u)

/* The transducer OD (1000h, 1001h, 1008h-100Ah, 1017h, 1018h, 1800h,
 * 2003h, 2004h:1, 2005h:1) plus the test objects above. */
co_od *fx_od_new(void);

#endif
