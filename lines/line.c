/* SPDX-License-Identifier: MIT */
/*
 * lines/line.c - the line thread and its epoll loop.
 *
 * One clock read per iteration (line_now_us), one timerfd armed at the
 * earliest of: the core's next deadline, the mailbox server's, the transmit
 * retry after ENOBUFS, and the watchdog check-in (so an idle line still
 * proves it is alive). No fixed tick, no busy polling.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/timerfd.h>
#include <time.h>
#include <unistd.h>

#include "core/commfault.h"
#include "core/heartbeat.h"
#include "core/nmt.h"
#include "lines/log.h"

enum {
	TAG_CAN = 1,
	TAG_TIMER,
	TAG_MBX,
	TAG_WAKE,
	TAG_EXT_WAKE /* + extension index */
};

#define RX_BATCH 32
#define PUBLISH_PERIOD_US 1000000u

uint64_t line_now_us(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static int line_send(void *ctx, const co_frame *f)
{
	line *l = ctx;
	return can_port_send(l->port, f, l->now_us);
}

static int epoll_add(int ep, int fd, uint32_t events, uint32_t tag)
{
	struct epoll_event ev = { .events = events, .data.u32 = tag };
	return epoll_ctl(ep, EPOLL_CTL_ADD, fd, &ev) ? -errno : 0;
}

/* Start-up of the extensions: watch their wake fds, then attach them in
 * order. One that fails is logged by name and fails the line. */
static int attach_extensions(line *l)
{
	for (unsigned i = 0; i < LINE_EXT_MAX; i++) {
		const line_ext *x = &l->p.ext[i];
		int rc;
		if (!x->ops)
			continue;
		if (x->ops->on_wake && x->wake_fd >= 0 &&
		    (rc = epoll_add(l->epfd, x->wake_fd, EPOLLIN, TAG_EXT_WAKE + i)) < 0) {
			cogw_log(COGW_LOG_ERR,
				 "line %s: extension %s: cannot watch its wake fd: %s", l->name,
				 x->ops->name ? x->ops->name : "?", strerror(-rc));
			return rc;
		}
		if (x->ops->attach && (rc = x->ops->attach(x->ctx, l)) < 0) {
			cogw_log(COGW_LOG_ERR, "line %s: extension %s: cannot attach: %s", l->name,
				 x->ops->name ? x->ops->name : "?", strerror(-rc));
			return rc;
		}
		l->ext_attached = i + 1;
	}
	return 0;
}

static void detach_extensions(line *l)
{
	for (unsigned i = l->ext_attached; i-- > 0;) {
		const line_ext *x = &l->p.ext[i];
		if (x->ops && x->ops->detach)
			x->ops->detach(x->ctx, l);
	}
	l->ext_attached = 0;
}

/* Each extension runs what is due; the earliest next time. */
static uint64_t poll_extensions(line *l)
{
	uint64_t next = UINT64_MAX;
	for (unsigned i = 0; i < l->ext_attached; i++) {
		const line_ext *x = &l->p.ext[i];
		if (x->ops && x->ops->poll) {
			uint64_t t = x->ops->poll(x->ctx, l, l->now_us);
			if (t < next)
				next = t;
		}
	}
	return next;
}

static void extensions_before_events(line *l)
{
	for (unsigned i = 0; i < l->ext_attached; i++) {
		const line_ext *x = &l->p.ext[i];
		if (x->ops && x->ops->before_events)
			x->ops->before_events(x->ctx, l);
	}
}

/* An eventfd (not EFD_SEMAPHORE) or a timerfd: one read returns the whole
 * count and resets it, so a second read could only fail with EAGAIN. On the
 * forwarding path that second system call sat between the wake-up and the
 * work (a few µs each under emulation). */
static void drain_fd(int fd)
{
	uint64_t v;
	(void)!read(fd, &v, sizeof v);
}

static void wake_extension(line *l, unsigned i)
{
	const line_ext *x = i < l->ext_attached ? &l->p.ext[i] : NULL;
	if (!x || !x->ops)
		return;
	/* read the counter first: a hand-off pushed after this read wakes us
	 * again, one pushed before it is taken by on_wake below */
	drain_fd(x->wake_fd);
	if (x->ops->on_wake)
		x->ops->on_wake(x->ctx, l);
}

/* The core instance, its pending-request table, 1010h/1011h, the mailbox. */
static int create_node_and_mailbox(line *l)
{
	const line_params *p = &l->p;
	int rc;
	co_node_config nc = p->node;
	nc.send = line_send;
	nc.send_ctx = l;
	nc.event = line_on_core_event;
	nc.event_ctx = l;
	if ((rc = co_node_create(&l->node, &nc)) < 0) {
		cogw_log(COGW_LOG_ERR, "line %s: cannot create the CANopen node %u: %s", l->name,
			 p->node.node_id, strerror(-rc));
		return rc;
	}
	if ((rc = line_health_attach(l)) < 0)
		return rc;
	line_appwd_attach(l);
	if ((rc = line_pending_init(&l->pending,
				    p->mbx.max_transfer ? p->mbx.max_transfer : 1024u * 1024u,
				    p->mbx.budget)) < 0)
		return rc;
	if (l->state_path[0] && (rc = line_store_attach(l)) < 0)
		return rc;
	mbx_server_config mc = p->mbx;
	mc.line = p->index;
	mc.dispatch.dispatch = line_dispatch;
	mc.dispatch.client_gone = line_client_gone;
	mc.dispatch_ctx = l;
	if ((rc = mbx_server_create(&l->mbx, &mc)) < 0) {
		cogw_log(COGW_LOG_ERR, "line %s: cannot create mailbox queue %s: %s", l->name,
			 mc.queue_name ? mc.queue_name : "?", strerror(-rc));
		return rc;
	}
	return 0;
}

/* What the thread sleeps on (the extensions' wake fds: attach_extensions). */
static int create_epoll_set(line *l)
{
	int rc;
	l->epfd = epoll_create1(EPOLL_CLOEXEC);
	l->timerfd = timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC);
	l->wakefd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
	if (l->epfd < 0 || l->timerfd < 0 || l->wakefd < 0) {
		rc = -errno;
		cogw_log(COGW_LOG_ERR, "line %s: epoll/timerfd/eventfd: %s", l->name,
			 strerror(-rc));
		return rc;
	}
	if ((rc = epoll_add(l->epfd, can_port_fd(l->port), EPOLLIN, TAG_CAN)) ||
	    (rc = epoll_add(l->epfd, l->timerfd, EPOLLIN, TAG_TIMER)) ||
	    (rc = epoll_add(l->epfd, mbx_server_fd(l->mbx), EPOLLIN, TAG_MBX)) ||
	    (rc = epoll_add(l->epfd, l->wakefd, EPOLLIN, TAG_WAKE)))
		return rc;
	return 0;
}

int line_create(line **out, const line_params *p)
{
	*out = NULL;
	line *l = calloc(1, sizeof *l);
	if (!l)
		return -ENOMEM;
	l->p = *p;
	l->epfd = l->timerfd = l->wakefd = -1;
	snprintf(l->name, sizeof l->name, "%s", p->name ? p->name : "line");
	snprintf(l->ifname, sizeof l->ifname, "%s", p->can.ifname ? p->can.ifname : "");
	l->p.name = l->name;
	l->p.can.ifname = l->ifname;
	if (!l->p.checkin_ms)
		l->p.checkin_ms = 500;
	if (!l->p.id_conflict_quiet_ms)
		l->p.id_conflict_quiet_ms = CO_COMMFAULT_ID_COLLISION_QUIET_MS;
	if (!l->p.fault_quiet_ms)
		l->p.fault_quiet_ms = CO_COMMFAULT_LOST_QUIET_MS;
	l->armed_us = UINT64_MAX;
	atomic_init(&l->hb_producer_ms, -1);
	pthread_mutex_init(&l->stats_lock, NULL);

	int rc;
	const char *why = NULL;
	l->store.blob = malloc(LINE_STORE_MAX);
	if (!l->store.blob) {
		rc = -ENOMEM;
		goto fail;
	}
	if ((rc = can_port_open(&l->port, &l->p.can, &why)) < 0) {
		cogw_log(COGW_LOG_ERR, "line %s (%s): cannot open the CAN interface: %s: %s",
			 l->name, l->ifname, why ? why : "?", strerror(-rc));
		goto fail;
	}

	if (p->state_dir && *p->state_dir) {
		snprintf(l->state_path, sizeof l->state_path, "%s/%s.od", p->state_dir, l->name);
		line_store_load(l);
	}

	if ((rc = create_node_and_mailbox(l)) < 0 || (rc = line_app_attach(l)) < 0 ||
	    (rc = create_epoll_set(l)) < 0 || (rc = attach_extensions(l)) < 0)
		goto fail;
	*out = l;
	return 0;
fail:
	line_destroy(l);
	return rc < 0 ? rc : -EIO;
}

/* Re-arm only when the deadline moves earlier (or the timer has fired):
 * most frames push a deadline later (a heartbeat restarts its consumer
 * timer), and one timerfd_settime per frame would cost more than the
 * occasional early wake-up that finds nothing due and re-arms. */
static void arm_timer(line *l, uint64_t at_us)
{
	if (at_us >= l->armed_us)
		return;
	l->armed_us = at_us;
	struct itimerspec its = { 0 };
	if (at_us != UINT64_MAX) {
		/* 0 would disarm: an already-expired deadline fires at once */
		if (at_us == 0)
			at_us = 1;
		its.it_value.tv_sec = (time_t)(at_us / 1000000u);
		its.it_value.tv_nsec = (long)(at_us % 1000000u) * 1000;
	}
	timerfd_settime(l->timerfd, TFD_TIMER_ABSTIME, &its, NULL);
}

static void set_epollout(line *l, bool on)
{
	if (on == l->epollout)
		return;
	l->epollout = on;
	struct epoll_event ev = { .events = EPOLLIN | (on ? EPOLLOUT : 0), .data.u32 = TAG_CAN };
	epoll_ctl(l->epfd, EPOLL_CTL_MOD, can_port_fd(l->port), &ev);
}

static void handle_can(line *l)
{
	can_rx_item items[RX_BATCH];
	/* Bounded: a flooded bus must not starve the mailbox and timers;
	 * epoll reports the socket again on the next iteration. */
	for (int round = 0; round < 8; round++) {
		int n = can_port_recv(l->port, items, RX_BATCH, l->now_us);
		if (n <= 0) {
			if (n == -ENETDOWN || n == -ENODEV || n == -ENXIO) {
				line_link_lost(l, -n);
			} else if (n < 0) {
				cogw_log(COGW_LOG_WARNING, "line %s: CAN receive: %s", l->name,
					 strerror(-n));
				l->link_events++;
			}
			return;
		}
		line_link_frame_heard(l);
		for (int i = 0; i < n; i++) {
			if (items[i].is_error) {
				line_on_can_error(l, &items[i]);
				continue;
			}
			co_node_recv(l->node, &items[i].frame, l->now_us);
			if (l->raw_subscribers)
				line_publish_raw(l, &items[i].frame, items[i].kernel_ts_ns);
		}
		if (n < RX_BATCH)
			return;
	}
}

/* handle_can() publishes raw frames only while some client subscribed to
 * the raw class (building an event per frame for nobody is waste). The
 * cache was never set before, so raw events never reached anyone: it is
 * refreshed after every batch of mailbox commands, which is where
 * SUBSCRIBE/UNSUBSCRIBE/UNREGISTER arrive. A reaped client can leave it
 * set until the next command; publishing then reaches nobody, harmlessly. */
static void refresh_raw_subscribers(line *l)
{
	l->raw_subscribers = mbx_server_subscribers(l->mbx, MBX_EVC_RAW);
	l->sync_subscribers = mbx_server_subscribers(l->mbx, MBX_EVC_SYNC);
}

static void handle_requests(line *l)
{
	unsigned stall = atomic_exchange(&l->stall_ms, 0);
	if (stall) {
		/* Test hook: a line that stops looping must stop the watchdog. */
		cogw_log(COGW_LOG_WARNING, "line %s: stalling for %u ms on request (test hook)",
			 l->name, stall);
		struct timespec ts = { .tv_sec = stall / 1000u,
				       .tv_nsec = (long)(stall % 1000u) * 1000000L };
		while (nanosleep(&ts, &ts) == -1 && errno == EINTR)
			;
	}
	int hb = atomic_exchange(&l->hb_producer_ms, -1);
	if (hb >= 0)
		co_hb_producer_set(l->node, (uint16_t)hb, l->now_us);
	if (atomic_load_explicit(&l->access.state, memory_order_acquire) == 1) {
		line_access_req *a = &l->access;
		if (mbx_server_set_rules(l->mbx, a->rules, a->n_rules, a->default_access) < 0)
			cogw_log(COGW_LOG_ERR,
				 "line %s: reload: access rules refused by the mailbox", l->name);
		mbx_server_set_lease(l->mbx, a->lease_ms);
		atomic_store_explicit(&a->state, 0, memory_order_release);
	}
	line_nodes_poll(l);
	line_store_poll(l);
}

static void publish_stats(line *l)
{
	if (l->now_us < l->next_publish_us)
		return;
	if (pthread_mutex_trylock(&l->stats_lock) != 0)
		return; /* the main thread is reading; try next iteration */
	const can_port_stats *cs = can_port_get_stats(l->port);
	const co_node_stats *ns = co_node_get_stats(l->node);
	const mbx_server_stats *ms = mbx_server_stats_get(l->mbx);
	line_stats *s = &l->published;
	s->loops = l->loops;
	s->max_loop_us = l->max_loop_us;
	s->rx_frames = cs->rx_frames;
	s->tx_frames = cs->tx_frames;
	s->rx_error_frames = cs->rx_error_frames;
	s->rx_overflow_drops = cs->rx_overflow_drops;
	s->tx_drops = cs->tx_drops;
	s->tx_errors = cs->tx_errors;
	s->bus_load_permille = cs->bus_load_permille;
	s->bus_state = (uint8_t)can_port_bus_state(l->port);
	s->core_rx_invalid = ns->rx_invalid;
	s->core_tx_failed = ns->tx_failed;
	s->nmt_state = co_nmt_get_state(l->node);
	uint16_t seen = 0;
	for (int i = 1; i < LINE_NODES; i++)
		seen += co_hb_remote_state(l->node, (uint8_t)i) != CO_HB_STATE_UNKNOWN;
	s->nodes_seen = seen;
	s->mbx_clients = ms->clients;
	s->mbx_commands = ms->commands_ok;
	s->mbx_malformed = ms->malformed_total;
	s->mbx_denied = ms->access_denied;
	s->mbx_dropped = ms->dropped;
	s->events_sent = ms->events_sent;
	l->have_stats = true;
	pthread_mutex_unlock(&l->stats_lock);
	l->next_publish_us = l->now_us + PUBLISH_PERIOD_US;
}

/* The earliest time the thread must wake: extensions and the TIME producer
 * (which also run what is due now), core, mailbox, transmit retry,
 * watchdog check-in. */
static uint64_t next_deadline(line *l, uint64_t checkin_period)
{
	uint64_t next = poll_extensions(l);
	uint64_t t = co_node_next_deadline_us(l->node);
	if (t < next)
		next = t;
	t = mbx_server_tick(l->mbx, l->now_us);
	if (t < next)
		next = t;
	t = can_port_retry_at_us(l->port);
	if (t < next)
		next = t;
	t = line_app_poll(l, l->now_us); /* indications' deadlines */
	if (t < next)
		next = t;
	t = line_time_poll(l); /* produces the TIME that is due */
	if (t < next)
		next = t;
	t = line_appwd_poll(l); /* trips the application watchdogs that are due */
	if (t < next)
		next = t;
	bool reopened = false;
	t = line_link_poll(l, &reopened); /* an interface that is down: is it back? */
	if (t < next)
		next = t;
	int rc = reopened ? epoll_add(l->epfd, can_port_fd(l->port), EPOLLIN, TAG_CAN) : 0;
	if (rc < 0)
		cogw_log(COGW_LOG_ERR, "line %s (%s): cannot watch the new socket: %s", l->name,
			 l->ifname, strerror(-rc));
	if (l->now_us + checkin_period / 2 < next)
		next = l->now_us + checkin_period / 2;
	return next;
}

static void handle_event(line *l, const struct epoll_event *ev)
{
	switch (ev->data.u32) {
	case TAG_CAN:
		if (ev->events & EPOLLOUT)
			can_port_flush(l->port, l->now_us);
		if (ev->events & (EPOLLIN | EPOLLERR))
			handle_can(l);
		break;
	case TAG_TIMER:
		drain_fd(l->timerfd);
		l->armed_us = UINT64_MAX; /* expired: re-arm */
		break;
	case TAG_MBX:
		mbx_server_poll(l->mbx, l->now_us);
		refresh_raw_subscribers(l);
		break;
	case TAG_WAKE:
		drain_fd(l->wakefd);
		handle_requests(l);
		break;
	default:
		wake_extension(l, ev->data.u32 - TAG_EXT_WAKE);
		break;
	}
}

/* After the events of one iteration: the core's timers, a transmit retry,
 * the bus health (lost frames, the transmit queue's watermarks). */
static void run_due(line *l)
{
	/* before the core: an indication's deadline is the SDO server's
	 * timeout, and the line's own abort must win (docs/sdo-answers.md) */
	line_app_poll(l, l->now_us);
	if (l->now_us >= co_node_next_deadline_us(l->node))
		co_node_tick(l->node, l->now_us);
	if (can_port_retry_at_us(l->port) <= l->now_us)
		can_port_flush(l->port, l->now_us);
	line_health_poll(l);
}

static void *line_main(void *arg)
{
	line *l = arg;
	uint64_t checkin_period = (uint64_t)l->p.checkin_ms * 1000u;
	l->now_us = line_now_us();
	co_node_tick(l->node, l->now_us);
	line_store_started(l);
	/* Publish once before saying "up": the main thread builds the STATUS=
	 * that goes with READY=1 from these counters, and without them it
	 * reported every line as "starting" at the moment it declared the
	 * daemon ready. */
	publish_stats(l);
	atomic_store(&l->up, true);

	while (!atomic_load(&l->stop)) {
		arm_timer(l, next_deadline(l, checkin_period));
		set_epollout(l, can_port_wants_writable(l->port));

		struct epoll_event evs[8];
		int n = epoll_wait(l->epfd, evs, 8, -1);
		uint64_t woke = line_now_us();
		l->now_us = woke;
		/* read by the watchdog only: no ordering with anything else */
		atomic_store_explicit(&l->checkin_us, woke, memory_order_relaxed);
		if (n < 0 && errno != EINTR) {
			cogw_log(COGW_LOG_ERR, "line %s: epoll_wait: %s", l->name, strerror(errno));
			break;
		}
		extensions_before_events(l);
		for (int i = 0; i < n; i++)
			handle_event(l, &evs[i]);
		run_due(l);
		/* The loop's duration is sampled, one loop in 64: a second clock
		 * read per wake-up is a system call where the clock has no vDSO
		 * (in a VM), on every request and every frame batch. */
		if ((++l->loops & 63) == 0) {
			uint64_t took = line_now_us() - woke;
			if (took > l->max_loop_us)
				l->max_loop_us = took;
		}
		publish_stats(l);
	}
	atomic_store(&l->up, false);
	return NULL;
}

static void apply_rt(line *l, pthread_attr_t *attr)
{
	if (l->p.rt_priority > 0) {
		struct sched_param sp = { .sched_priority = l->p.rt_priority };
		pthread_attr_setinheritsched(attr, PTHREAD_EXPLICIT_SCHED);
		pthread_attr_setschedpolicy(attr, SCHED_FIFO);
		pthread_attr_setschedparam(attr, &sp);
	}
}

int line_set_rt(line *l, int priority, int cpu)
{
	struct sched_param sp = { .sched_priority = priority > 0 ? priority : 0 };
	cpu_set_t set;
	int rc;

	if (!l->started)
		return -ESRCH;
	rc = pthread_setschedparam(l->thread, priority > 0 ? SCHED_FIFO : SCHED_OTHER, &sp);
	if (rc)
		return -rc;
	CPU_ZERO(&set);
	if (cpu >= 0)
		CPU_SET(cpu, &set);
	else /* unpinned: every CPU the process may use */
		(void)sched_getaffinity(0, sizeof set, &set);
	if ((rc = pthread_setaffinity_np(l->thread, sizeof set, &set)))
		return -rc;
	l->p.rt_priority = priority;
	l->p.rt_cpu = cpu;
	return 0;
}

int line_start(line *l)
{
	pthread_attr_t attr;
	pthread_attr_init(&attr);
	apply_rt(l, &attr);
	atomic_store(&l->checkin_us, line_now_us());
	int rc = pthread_create(&l->thread, &attr, line_main, l);
	if (rc == EPERM && l->p.rt_priority > 0) {
		cogw_log(COGW_LOG_WARNING,
			 "line %s: SCHED_FIFO priority %d not permitted (needs CAP_SYS_NICE or an "
			 "RT limit); running with normal scheduling",
			 l->name, l->p.rt_priority);
		pthread_attr_destroy(&attr);
		pthread_attr_init(&attr);
		rc = pthread_create(&l->thread, &attr, line_main, l);
	}
	pthread_attr_destroy(&attr);
	if (rc) {
		cogw_log(COGW_LOG_ERR, "line %s: cannot start its thread: %s", l->name,
			 strerror(rc));
		return -rc;
	}
	l->started = true;
	/* thread names hold 15 characters: "cogw-" + the start of the name */
	char tname[16] = "cogw-";
	size_t keep = strnlen(l->name, sizeof tname - 6);
	memcpy(tname + 5, l->name, keep);
	tname[5 + keep] = '\0';
	pthread_setname_np(l->thread, tname);
	if (l->p.rt_cpu >= 0) {
		cpu_set_t set;
		CPU_ZERO(&set);
		CPU_SET(l->p.rt_cpu, &set);
		rc = pthread_setaffinity_np(l->thread, sizeof set, &set);
		if (rc)
			cogw_log(COGW_LOG_WARNING,
				 "line %s: cannot pin to CPU %d: %s; running unpinned", l->name,
				 l->p.rt_cpu, strerror(rc));
	}
	return 0;
}

void line_stop(line *l)
{
	if (!l || !l->started)
		return;
	atomic_store(&l->stop, true);
	line_wake(l);
	pthread_join(l->thread, NULL);
	l->started = false;
}

void line_destroy(line *l)
{
	if (!l)
		return;
	line_stop(l);
	detach_extensions(l);
	line_app_detach(l);
	mbx_server_destroy(l->mbx);
	co_node_destroy(l->node);
	can_port_close(l->port);
	if (l->epfd >= 0)
		close(l->epfd);
	if (l->timerfd >= 0)
		close(l->timerfd);
	if (l->wakefd >= 0)
		close(l->wakefd);
	line_pending_fini(&l->pending);
	free(l->store.blob);
	free(l->store.factory);
	pthread_mutex_destroy(&l->stats_lock);
	free(l);
}

co_node *line_node(line *l)
{
	return l->node;
}

mbx_server *line_mbx(line *l)
{
	return l->mbx;
}

uint8_t line_index(const line *l)
{
	return l->p.index;
}

uint16_t line_network_id(const line *l)
{
	return l->p.network_id;
}

uint64_t line_loop_now_us(const line *l)
{
	return l->now_us;
}

co_pdo_layout *line_pdo_layout(line *l)
{
	return l->p.pdo_layout;
}

const char *line_name(const line *l)
{
	return l->name;
}

size_t line_buffer_bytes(const line *l)
{
	size_t per = l->p.mbx.max_transfer ? l->p.mbx.max_transfer : 1024u * 1024u;
	return per * LINE_BIG_SLOTS + LINE_STORE_MAX + mbx_server_buffer_bytes(l->mbx);
}

uint64_t line_last_checkin_us(const line *l)
{
	return atomic_load(&((line *)l)->checkin_us);
}

bool line_is_up(const line *l)
{
	return atomic_load(&((line *)l)->up);
}

bool line_can_carry(const line *l)
{
	return line_is_up(l) && can_port_bus_state(l->port) != CAN_BUS_OFF &&
	       can_port_link_up(l->port);
}

uint32_t line_link_events(const line *l)
{
	return l->link_events;
}

const char *line_ifname(const line *l)
{
	return l->ifname;
}

bool line_tx_idle(const line *l)
{
	return can_port_tx_queued(l->port) == 0 && can_port_bus_state(l->port) != CAN_BUS_OFF;
}

int line_ignore_own_tpdos(line *l, const co_frame *ids, size_t n)
{
	return can_port_ignore_data(l->port, ids, n);
}

bool line_stats_snapshot(line *l, line_stats *out)
{
	pthread_mutex_lock(&l->stats_lock);
	bool have = l->have_stats;
	if (have)
		*out = l->published;
	pthread_mutex_unlock(&l->stats_lock);
	return have;
}

void line_request_stall(line *l, unsigned ms)
{
	atomic_store(&l->stall_ms, ms);
	line_wake(l);
}

void line_request_hb_producer(line *l, uint16_t ms)
{
	atomic_store(&l->hb_producer_ms, (int)ms);
	line_wake(l);
}

int line_request_access(line *l, const mbx_access_rule *rules, size_t n_rules,
			uint8_t default_access, unsigned lease_ms)
{
	if (n_rules > MBX_SERVER_RULES_MAX)
		return -EINVAL;
	/* A previous hand-over not yet taken: the line loops at least every
	 * checkin_ms/2, so waiting a little is enough unless it is stuck;
	 * then the fields must not be overwritten under it. */
	if (!line_wait_state_leaves(&l->access.state, 1))
		return -EBUSY;
	line_access_req *a = &l->access;
	if (n_rules)
		memcpy(a->rules, rules, n_rules * sizeof *rules);
	a->n_rules = n_rules;
	a->default_access = default_access;
	a->lease_ms = lease_ms;
	atomic_store_explicit(&a->state, 1, memory_order_release);
	line_wake(l);
	/* Wait (briefly) until the line has applied it, so that the READY=1
	 * after a reload means the new rules are in force. A stuck line
	 * applies it later. */
	return line_wait_state_leaves(&l->access.state, 1) ? 0 : -ETIMEDOUT;
}
