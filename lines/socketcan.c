/* SPDX-License-Identifier: MIT */
/*
 * lines/socketcan.c - SocketCAN port of one line. See socketcan.h for the
 * back-pressure contract.
 */
#include "lines/socketcan.h"

#include <errno.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#define RX_BATCH 32
#define RETRY_MIN_US 250u
#define RETRY_MAX_US 8000u

struct can_port {
	int fd;
	unsigned ifindex;
	char ifname[IFNAMSIZ]; /* cfg.ifname points here */
	can_port_config cfg;
	can_port_stats stats;
	can_bus_state state;

	co_frame *txq; /* ring */
	uint16_t tx_head, tx_count;
	bool wants_writable;
	uint64_t retry_at_us;
	uint32_t retry_backoff_us;
	bool above_high;
	int watermark_event;

	uint32_t last_ovfl; /* cumulative kernel drop count last seen */
	int link_error;     /* ENETDOWN/ENODEV/ENXIO a send met (0 = none) */
	/* the receive filter given (can_port_ignore_data), applied again
	 * to the socket of a re-opened port */
	struct can_filter ignore[CAN_PORT_IGNORE_MAX];
	uint8_t n_ignore;
	uint64_t load_window_start_us;
	uint64_t load_bits;
};

const char *can_bus_state_to_string(can_bus_state s)
{
	switch (s) {
	case CAN_BUS_ACTIVE:
		return "error-active";
	case CAN_BUS_WARNING:
		return "error-warning";
	case CAN_BUS_PASSIVE:
		return "error-passive";
	case CAN_BUS_OFF:
		return "bus-off";
	}
	return "?";
}

void can_error_decode(uint32_t can_id, const uint8_t data[8], can_bus_state current,
		      can_error_info *out)
{
	memset(out, 0, sizeof *out);
	uint32_t cls = can_id & CAN_ERR_MASK;
	can_bus_state next = current;

	out->raw_class = cls;
	out->tx_timeout = cls & CAN_ERR_TX_TIMEOUT;
	out->lost_arbitration = cls & CAN_ERR_LOSTARB;
	out->no_ack = cls & CAN_ERR_ACK;
	out->bus_error = cls & CAN_ERR_BUSERROR;
	out->protocol_violation = cls & CAN_ERR_PROT;
	if (cls & CAN_ERR_CNT) {
		out->tx_errors = data[6];
		out->rx_errors = data[7];
	}
	if (cls & CAN_ERR_CRTL) {
		uint8_t c = data[1];
		out->rx_overflow = c & CAN_ERR_CRTL_RX_OVERFLOW;
		out->tx_overflow = c & CAN_ERR_CRTL_TX_OVERFLOW;
		out->controller_problem = out->rx_overflow || out->tx_overflow;
		if (c & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE))
			next = CAN_BUS_PASSIVE;
		else if (c & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING))
			next = CAN_BUS_WARNING;
		else if (c & CAN_ERR_CRTL_ACTIVE)
			next = CAN_BUS_ACTIVE;
	}
	if (cls & CAN_ERR_BUSOFF)
		next = CAN_BUS_OFF;
	if (cls & CAN_ERR_RESTARTED) {
		/* The driver restarted the controller after bus-off: it comes
		 * back error-active (ISO 11898-1 recovery sequence). */
		out->restarted = true;
		next = CAN_BUS_ACTIVE;
	}
	out->state = next;
	out->state_changed = next != current;
}

/* Bits a frame occupies on the wire, stuffing approximated at +10 %:
 * good enough for a load figure, not for scheduling. */
static uint32_t frame_bits(const co_frame *f)
{
	uint32_t bits = (f->flags & CO_FRAME_EXT) ? 67u : 47u;
	if (!(f->flags & CO_FRAME_RTR))
		bits += 8u * f->len;
	return bits + bits / 10u;
}

static void load_account(can_port *p, uint32_t bits, uint64_t now_us)
{
	if (now_us - p->load_window_start_us >= 1000000u) {
		uint64_t elapsed = now_us - p->load_window_start_us;
		/* a quiet gap of several seconds counts as zero load */
		if (elapsed < 2000000u && p->cfg.bitrate)
			p->stats.bus_load_permille = (uint32_t)(p->load_bits * 1000u /
								p->cfg.bitrate);
		else
			p->stats.bus_load_permille = 0;
		p->load_window_start_us = now_us;
		p->load_bits = 0;
	}
	p->load_bits += bits;
}

static int set_opt(int fd, int level, int name, const void *v, socklen_t len, const char *what,
		   const char **errmsg)
{
	if (setsockopt(fd, level, name, v, len) == 0)
		return 0;
	if (errmsg)
		*errmsg = what;
	return -errno;
}

/* A raw socket on the port's interface, by name (a re-created interface
 * has another index), with error frames, timestamps, overflow counting,
 * the buffers and the receive filter the port wants; it becomes the
 * port's socket only once complete. */
static int port_socket(can_port *p, const char **errmsg)
{
	int rc;
	int fd = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
	if (fd < 0) {
		rc = -errno;
		if (errmsg)
			*errmsg = "socket(PF_CAN): kernel without CAN support or not permitted";
		goto fail;
	}
	unsigned ifindex = if_nametoindex(p->cfg.ifname);
	if (!ifindex) {
		rc = -ENODEV;
		if (errmsg)
			*errmsg = "no such network interface";
		goto fail;
	}
	can_err_mask_t err_mask = CAN_ERR_MASK;
	int on = 1, zero = 0;
	if ((rc = set_opt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask,
			  "enable error frames", errmsg)) ||
	    (rc = set_opt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on,
			  "enable kernel timestamps", errmsg)) ||
	    (rc = set_opt(fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on,
			  "enable receive overflow counting", errmsg)))
		goto fail;
	/* A big receive buffer rides out a slow consumer; FORCE needs
	 * CAP_NET_ADMIN, the plain option is capped by rmem_max. */
	if (setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &p->cfg.rcvbuf_bytes, sizeof(int)) != 0)
		(void)setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &p->cfg.rcvbuf_bytes, sizeof(int));
	/* The smallest send buffer makes a full kernel queue show up as EAGAIN
	 * (which EPOLLOUT clears) rather than ENOBUFS from the qdisc (which
	 * nothing signals). Our own queue holds the backlog instead. */
	(void)setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &zero, sizeof zero);

	struct sockaddr_can addr = { .can_family = AF_CAN, .can_ifindex = (int)ifindex };
	if (bind(fd, (struct sockaddr *)&addr, sizeof addr) != 0) {
		rc = -errno;
		if (errmsg)
			*errmsg = "bind to the CAN interface";
		goto fail;
	}
	if (p->n_ignore &&
	    (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_JOIN_FILTERS, &on, sizeof on) != 0 ||
	     setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, p->ignore,
			(socklen_t)(p->n_ignore * sizeof p->ignore[0])) != 0)) {
		rc = -errno;
		if (errmsg)
			*errmsg = "receive filter";
		goto fail;
	}
	if (p->fd >= 0)
		close(p->fd);
	p->fd = fd;
	p->ifindex = ifindex;
	return 0;
fail:
	if (fd >= 0)
		close(fd);
	return rc;
}

int can_port_open(can_port **out, const can_port_config *cfg, const char **errmsg)
{
	*out = NULL;
	if (!cfg->ifname || !*cfg->ifname || strlen(cfg->ifname) >= IFNAMSIZ) {
		if (errmsg)
			*errmsg = "interface name empty or too long";
		return -EINVAL;
	}
	can_port *p = calloc(1, sizeof *p);
	if (!p)
		return -ENOMEM;
	p->fd = -1;
	p->cfg = *cfg;
	snprintf(p->ifname, sizeof p->ifname, "%s", cfg->ifname);
	p->cfg.ifname = p->ifname;
	if (!p->cfg.tx_queue_len)
		p->cfg.tx_queue_len = 256;
	if (!p->cfg.tx_high_water || p->cfg.tx_high_water > 100)
		p->cfg.tx_high_water = 75;
	if (!p->cfg.tx_low_water || p->cfg.tx_low_water >= p->cfg.tx_high_water)
		p->cfg.tx_low_water = 25;
	if (!p->cfg.rcvbuf_bytes)
		p->cfg.rcvbuf_bytes = 256 * 1024;
	p->retry_at_us = UINT64_MAX;
	p->retry_backoff_us = RETRY_MIN_US;

	int rc = -ENOMEM;
	p->txq = calloc(p->cfg.tx_queue_len, sizeof *p->txq);
	if (!p->txq)
		goto fail;

	if ((rc = port_socket(p, errmsg)) < 0)
		goto fail;
	*out = p;
	return 0;
fail:
	can_port_close(p);
	return rc;
}

void can_port_close(can_port *p)
{
	if (!p)
		return;
	if (p->fd >= 0)
		close(p->fd);
	free(p->txq);
	free(p);
}

int can_port_fd(const can_port *p)
{
	return p->fd;
}

static void frame_from_kernel(const struct can_frame *k, co_frame *f)
{
	uint8_t len = k->len > CAN_MAX_DLEN ? CAN_MAX_DLEN : k->len;
	if (k->can_id & CAN_EFF_FLAG)
		co_frame_init(f, k->can_id & CAN_EFF_MASK, len);
	else
		co_frame_init(f, k->can_id & CAN_SFF_MASK, len);
	if (k->can_id & CAN_EFF_FLAG)
		f->flags |= CO_FRAME_EXT;
	if (k->can_id & CAN_RTR_FLAG)
		f->flags |= CO_FRAME_RTR;
	else
		memcpy(f->data, k->data, len);
}

static void read_cmsgs(can_port *p, struct msghdr *m, can_rx_item *it)
{
	for (struct cmsghdr *c = CMSG_FIRSTHDR(m); c; c = CMSG_NXTHDR(m, c)) {
		if (c->cmsg_level != SOL_SOCKET)
			continue;
		if (c->cmsg_type == SCM_TIMESTAMPNS) {
			struct timespec ts;
			memcpy(&ts, CMSG_DATA(c), sizeof ts);
			it->kernel_ts_ns = (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
		} else if (c->cmsg_type == SO_RXQ_OVFL) {
			uint32_t drops;
			memcpy(&drops, CMSG_DATA(c), sizeof drops);
			/* cumulative per socket; unsigned wrap-around is fine */
			p->stats.rx_overflow_drops += (uint32_t)(drops - p->last_ovfl);
			p->last_ovfl = drops;
		}
	}
}

int can_port_recv(can_port *p, can_rx_item *items, int max, uint64_t now_us)
{
	if (max > RX_BATCH)
		max = RX_BATCH;
	struct can_frame kf[RX_BATCH];
	struct iovec iov[RX_BATCH];
	struct mmsghdr mm[RX_BATCH];
	char ctl[RX_BATCH][CMSG_SPACE(sizeof(struct timespec)) + CMSG_SPACE(sizeof(uint32_t))];

	for (int i = 0; i < max; i++) {
		iov[i] = (struct iovec){ .iov_base = &kf[i], .iov_len = sizeof kf[i] };
		mm[i].msg_hdr = (struct msghdr){ .msg_iov = &iov[i],
						 .msg_iovlen = 1,
						 .msg_control = ctl[i],
						 .msg_controllen = sizeof ctl[i] };
		mm[i].msg_len = 0;
	}
	int n = recvmmsg(p->fd, mm, (unsigned)max, MSG_DONTWAIT, NULL);
	if (n < 0)
		return (errno == EAGAIN || errno == EINTR) ? 0 : -errno;

	int out = 0;
	for (int i = 0; i < n; i++) {
		can_rx_item *it = &items[out];
		memset(it, 0, sizeof *it);
		read_cmsgs(p, &mm[i].msg_hdr, it);
		if (mm[i].msg_len != sizeof(struct can_frame)) {
			p->stats.rx_invalid++;
			continue;
		}
		if (kf[i].can_id & CAN_ERR_FLAG) {
			it->is_error = true;
			can_error_decode(kf[i].can_id, kf[i].data, p->state, &it->error);
			if (it->error.state_changed && it->error.state == CAN_BUS_OFF)
				p->stats.bus_off_count++;
			p->state = it->error.state;
			p->stats.rx_error_frames++;
			frame_from_kernel(&kf[i], &it->frame);
			out++;
			continue;
		}
		frame_from_kernel(&kf[i], &it->frame);
		p->stats.rx_frames++;
		load_account(p, frame_bits(&it->frame), now_us);
		out++;
	}
	return out;
}

static void update_watermarks(can_port *p)
{
	uint32_t q = p->tx_count, cap = p->cfg.tx_queue_len;
	if (q > p->stats.tx_queued_max)
		p->stats.tx_queued_max = q;
	if (!p->above_high && q * 100u >= cap * p->cfg.tx_high_water) {
		p->above_high = true;
		p->watermark_event = 1;
	} else if (p->above_high && q * 100u <= cap * p->cfg.tx_low_water) {
		p->above_high = false;
		p->watermark_event = -1;
	}
}

static int write_frame(int fd, const co_frame *f)
{
	struct can_frame k = { 0 };
	k.can_id = f->id;
	if (f->flags & CO_FRAME_EXT)
		k.can_id |= CAN_EFF_FLAG;
	if (f->flags & CO_FRAME_RTR)
		k.can_id |= CAN_RTR_FLAG;
	k.len = f->len;
	memcpy(k.data, f->data, f->len);
	ssize_t n = write(fd, &k, sizeof k);
	if (n == (ssize_t)sizeof k)
		return 0;
	return n < 0 ? -errno : -EIO;
}

static int write_one(can_port *p, const co_frame *f)
{
	return write_frame(p->fd, f);
}

int can_port_flush(can_port *p, uint64_t now_us)
{
	int sent = 0;
	p->wants_writable = false;
	while (p->tx_count) {
		const co_frame *f = &p->txq[p->tx_head];
		int rc = write_one(p, f);
		if (rc == -EAGAIN) {
			p->stats.tx_eagain++;
			p->wants_writable = true;
			break;
		}
		if (rc == -ENOBUFS) {
			p->stats.tx_enobufs++;
			p->retry_at_us = now_us + p->retry_backoff_us;
			if (p->retry_backoff_us < RETRY_MAX_US)
				p->retry_backoff_us *= 2;
			break;
		}
		if (rc == 0) {
			p->stats.tx_frames++;
			load_account(p, frame_bits(f), now_us);
			sent++;
			p->retry_backoff_us = RETRY_MIN_US;
			p->retry_at_us = UINT64_MAX;
		} else {
			/* e.g. ENETDOWN: the frame cannot go out; drop it rather
			 * than wedge the queue behind it. A send takes the
			 * socket's pending error (sock_error), so the receive
			 * side may never see it: the interface's loss is kept
			 * for can_port_take_link_error(). */
			p->stats.tx_errors++;
			if (rc == -ENETDOWN || rc == -ENODEV || rc == -ENXIO)
				p->link_error = -rc;
		}
		p->tx_head = (uint16_t)((p->tx_head + 1u) % p->cfg.tx_queue_len);
		p->tx_count--;
	}
	update_watermarks(p);
	return sent;
}

int can_port_send(can_port *p, const co_frame *f, uint64_t now_us)
{
	if (!co_frame_is_valid(f))
		return -EINVAL;
	if (p->tx_count >= p->cfg.tx_queue_len) {
		p->stats.tx_drops++;
		return -ENOBUFS;
	}
	uint16_t tail = (uint16_t)((p->tx_head + p->tx_count) % p->cfg.tx_queue_len);
	p->txq[tail] = *f;
	p->tx_count++;
	/* Keep order: only write through when nothing is waiting already. */
	if (p->tx_count == 1 && !p->wants_writable && p->retry_at_us == UINT64_MAX)
		can_port_flush(p, now_us);
	else
		update_watermarks(p);
	return 0;
}

size_t can_port_tx_queued(const can_port *p)
{
	return p->tx_count;
}

bool can_port_wants_writable(const can_port *p)
{
	return p->wants_writable;
}

uint64_t can_port_retry_at_us(const can_port *p)
{
	return p->retry_at_us;
}

int can_port_take_watermark_event(can_port *p)
{
	int e = p->watermark_event;
	p->watermark_event = 0;
	return e;
}

bool can_port_link_up(const can_port *p)
{
	struct ifreq ifr = { .ifr_ifindex = p->ifindex };

	/* By index: the name may have changed since the port was opened.
	 * Asked on the port's own socket (if_indextoname would open and
	 * close one for every look). */
	if (ioctl(p->fd, SIOCGIFNAME, &ifr) != 0)
		return false; /* the interface is gone */
	if (ioctl(p->fd, SIOCGIFFLAGS, &ifr) != 0)
		return true; /* cannot tell: do not refuse on a guess */
	return (ifr.ifr_flags & IFF_UP) && (ifr.ifr_flags & IFF_RUNNING);
}

can_bus_state can_port_bus_state(const can_port *p)
{
	return p->state;
}

const can_port_stats *can_port_get_stats(const can_port *p)
{
	return &p->stats;
}

int can_port_ignore_data(can_port *p, const co_frame *ids, size_t n)
{
	struct can_filter f[CAN_PORT_IGNORE_MAX];
	int join = n > 0;

	if (n > CAN_PORT_IGNORE_MAX)
		return -EINVAL;
	for (size_t i = 0; i < n; i++) {
		bool ext = ids[i].flags & CO_FRAME_EXT;
		/* inverted: the frame passes unless it is a data frame with
		 * this identifier; joined: it must pass every one */
		f[i].can_id = ids[i].id | (ext ? CAN_EFF_FLAG : 0) | CAN_INV_FILTER;
		f[i].can_mask = (ext ? CAN_EFF_MASK : CAN_SFF_MASK) | CAN_EFF_FLAG | CAN_RTR_FLAG;
	}
	if (n == 0) { /* the default: everything */
		f[0].can_id = 0;
		f[0].can_mask = 0;
	}
	if (setsockopt(p->fd, SOL_CAN_RAW, CAN_RAW_JOIN_FILTERS, &join, sizeof join) != 0 ||
	    setsockopt(p->fd, SOL_CAN_RAW, CAN_RAW_FILTER, f,
		       (socklen_t)((n ? n : 1) * sizeof f[0])) != 0)
		return -errno;
	memcpy(p->ignore, f, n * sizeof f[0]);
	p->n_ignore = (uint8_t)n;
	return 0;
}

int can_port_reopen(can_port *p, uint64_t now_us, const char **errmsg)
{
	int rc = port_socket(p, errmsg);
	if (rc < 0)
		return rc;
	/* what waited for the old interface is lost with it */
	p->stats.tx_errors += p->tx_count;
	p->tx_head = p->tx_count = 0;
	p->wants_writable = false;
	p->retry_at_us = UINT64_MAX;
	p->retry_backoff_us = RETRY_MIN_US;
	p->state = CAN_BUS_ACTIVE;
	p->link_error = 0;
	p->last_ovfl = 0;
	p->load_window_start_us = now_us;
	p->load_bits = 0;
	update_watermarks(p);
	return 0;
}

int can_port_take_link_error(can_port *p)
{
	int e = p->link_error;
	p->link_error = 0;
	return e;
}

can_link_state can_port_link_state(const can_port *p)
{
	struct ifreq ifr;
	memset(&ifr, 0, sizeof ifr);
	snprintf(ifr.ifr_name, sizeof ifr.ifr_name, "%s", p->ifname);
	if (ioctl(p->fd, SIOCGIFINDEX, &ifr) != 0)
		return CAN_LINK_GONE;
	if ((unsigned)ifr.ifr_ifindex != p->ifindex)
		return CAN_LINK_REPLACED;
	if (ioctl(p->fd, SIOCGIFFLAGS, &ifr) != 0)
		return CAN_LINK_UP; /* cannot tell: do not refuse on a guess */
	return (ifr.ifr_flags & IFF_UP) && (ifr.ifr_flags & IFF_RUNNING) ? CAN_LINK_UP
									 : CAN_LINK_DOWN;
}

/* A socket that only sends: no receive filter matches, so nothing ever
 * queues on it; the default send buffer, so that a frame is refused
 * (EAGAIN/ENOBUFS) rather than queued when the interface is congested. */
int can_tx_socket_open(const char *ifname)
{
	if (!ifname || !*ifname || strlen(ifname) >= IFNAMSIZ)
		return -EINVAL;
	unsigned ifindex = if_nametoindex(ifname);
	if (!ifindex)
		return -ENODEV;
	int fd = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
	if (fd < 0)
		return -errno;
	struct sockaddr_can addr = { .can_family = AF_CAN, .can_ifindex = (int)ifindex };
	if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, NULL, 0) != 0 ||
	    bind(fd, (struct sockaddr *)&addr, sizeof addr) != 0) {
		int rc = -errno;
		close(fd);
		return rc;
	}
	return fd;
}

int can_tx_socket_send(int fd, const co_frame *f)
{
	if (f->len > 8)
		return -EINVAL;
	return write_frame(fd, f);
}
