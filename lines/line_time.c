/* SPDX-License-Identifier: MIT */
/*
 * lines/line_time.c - the TIME producer's clock (CiA 301 §7.2.6).
 *
 * CiA 301 gives the TIME producer no period object: when to send is the
 * application's business, and core/time.c frames TIME_OF_DAY without
 * reading any clock. The line does it every `time_period_ms` with the
 * system's wall clock (CLOCK_REALTIME, read only when a TIME is due),
 * on the line thread's own timer: deadlines step by whole periods from
 * the monotonic clock, so a wall-clock step changes the value sent, never
 * the rhythm; a late wake-up skips the periods it missed instead of
 * sending a burst.
 *
 * Whether a frame goes out is the core's decision: 1012h bit 30 (an SDO
 * write may clear it at run time) and the NMT state (not in STOPPED).
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <string.h>
#include <time.h>

#include "core/time.h"
#include "lines/log.h"

static int64_t wall_clock_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_REALTIME, &ts);
	return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

static void produce(line *l)
{
	co_time_of_day t;
	int rc = co_time_from_unix_ms(wall_clock_ms(), &t);
	if (rc < 0) {
		/* TIME_OF_DAY covers 1984..2163: a clock outside that (an unset
		 * RTC at 1970) has nothing to tell the devices */
		l->time_unusable++;
		if (!l->time_clock_logged)
			cogw_log(COGW_LOG_WARNING,
				 "line %s: TIME not produced: the system clock is outside "
				 "1984..2163",
				 l->name);
		l->time_clock_logged = true;
		return;
	}
	l->time_clock_logged = false;
	rc = co_time_send(l->node, &t, l->now_us);
	/* -EPERM: 1012h bit 30 cleared; -EAGAIN: STOPPED. A send error is
	 * counted by the core and the port like any other frame's. */
	(void)rc;
}

uint64_t line_time_poll(line *l)
{
	uint64_t period_us = (uint64_t)l->p.time_period_ms * 1000u;
	if (!period_us)
		return UINT64_MAX;
	if (l->now_us < l->time_next_us)
		return l->time_next_us;
	produce(l);
	l->time_next_us += period_us;
	if (l->time_next_us <= l->now_us)
		l->time_next_us = l->now_us + period_us;
	return l->time_next_us;
}
