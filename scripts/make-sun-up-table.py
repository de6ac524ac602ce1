#!/usr/bin/python3
"""Writes tests/data/sun_up_hours.csv: how many hours the sun is up over a
period at a site, by PyEphem (Debian's python3-ephem), the independent
reference for the sun samples of renderer/core/sun_hours.cpp (whose sun is
renderer/core/sun_position.cpp's NREL SPA).

    scripts/make-sun-up-table.py OUT.csv        write the table
    scripts/make-sun-up-table.py --check CSV    recompute it and compare (a ctest)

"Up" as core/sun_position.hpp's above_horizon has it: the apparent
(refracted) elevation of the centre of the sun's disc is above 0, for an
observer at 0 m, refraction for 1010 hPa and 10 C (SPA's and PyEphem's
standard atmosphere). In ephem that is an Observer at elevation 0, pressure
1010, temp 10, horizon 0, and the rising and setting of the sun's centre
(use_center=True), with ephem's own refraction.

How: the period is cut at the sun's culminations (ephem's transits and
antitransits), between which its altitude only climbs or only falls, so
each such half-day holds at most one rising or setting: one exactly when
the sun is up at one end and not at the other. That covers polar day and
polar night (no half-day changes state; ephem's next_rising and
next_setting would raise AlwaysUpError or NeverUpError there) and the days
between them. Each event is ephem's next_rising / next_setting from the
half-day's start, then narrowed by bisection on ephem's apparent altitude to
1e-5 s (ephem stops its own search within 0.1 s); where ephem raises a
CircumpolarError or lands outside the half-day (the sun grazing the
horizon), the bisection runs over the whole half-day. The hours are the
lengths of the intervals with the sun up, cut to [start, end): if the sun is
up at start, they count from start.

PyEphem's theory of the sun is built in (libastro: VSOP87), so this needs no
data download.

Columns:
  name                  the site
  latitude, longitude   of the observer, degrees (north, east positive)
  start, end            the period [start, end), RFC 3339 UTC
  sun_up_hours          hours in [start, end) with the sun up
"""
import datetime
import math
import sys

try:
    import ephem
except ImportError:
    sys.exit("make-sun-up-table: PyEphem is missing: install Debian's python3-ephem "
             "(bash scripts/install-deps.sh) and run this with /usr/bin/python3")

COLUMNS = ["name", "latitude", "longitude", "start", "end", "sun_up_hours"]
# Tolerance of --check, hours: the same ephem computes the same numbers; the
# slack only absorbs a different libm's last bits (an event moves by less
# than the bisection's 1e-5 s), which can tip the rounding of the sixth
# decimal: one unit of it, no more.
CHECK_TOLERANCE = 1.5e-6

SITES = [("equator", 0.0, 0.0), ("London", 51.5, -0.12), ("Tromso", 69.65, 18.96),
         ("Sydney", -33.87, 151.21), ("Reykjavik", 64.15, -21.94), ("McMurdo", -77.85, 166.67)]
# [start, end): the whole year 2026, an equinox and both solstices.
PERIODS = [((2026, 1, 1), (2027, 1, 1)), ((2026, 3, 21), (2026, 3, 22)),
           ((2026, 6, 21), (2026, 6, 22)), ((2026, 12, 21), (2026, 12, 22))]

SECOND = 1.0 / 86400.0  # in ephem's days
# Bisection stops when the bracket is this narrow (ephem's dates, days since
# 1899-12-31T12:00Z, resolve about 1e-6 s in this century).
BISECTION_WIDTH = 1e-5 * SECOND


def unix_of(year, month, day, seconds_of_day):
    # Days from 1970-01-01 (proleptic Gregorian), H. Hinnant's days_from_civil.
    y = year - (month <= 2)
    era = y // 400
    yoe = y - era * 400
    doy = (153 * (month + (-3 if month > 2 else 9)) + 2) // 5 + day - 1
    doe = yoe * 365 + yoe // 4 - yoe // 100 + doy
    return (era * 146097 + doe - 719468) * 86400 + seconds_of_day


def utc_text(t):
    d = datetime.datetime(1970, 1, 1) + datetime.timedelta(seconds=t)
    return d.strftime("%Y-%m-%dT%H:%M:%SZ")


def ephem_date(t):
    # ephem's dates are days since 1899-12-31T12:00Z (UT); 1970 is 25567.5.
    return t / 86400.0 + 25567.5


class Site:
    def __init__(self, lat, lon):
        self.obs = ephem.Observer()
        self.obs.lat = math.radians(lat)
        self.obs.lon = math.radians(lon)
        self.obs.elevation = 0.0
        self.obs.pressure = 1010.0
        self.obs.temp = 10.0
        self.obs.horizon = 0.0
        self.sun = ephem.Sun()

    def altitude(self, d):
        """Apparent altitude of the sun's centre at ephem date d, radians."""
        self.obs.date = d
        self.sun.compute(self.obs)
        return self.sun.alt

    def up(self, d):
        return self.altitude(d) > 0.0

    def culminations(self, start, end):
        """The sun's culminations from the last one at or before start to the
        first one at or after end, in order (ephem dates)."""
        before = max(float(self.obs.previous_transit(self.sun, start=start + SECOND)),
                     float(self.obs.previous_antitransit(self.sun, start=start + SECOND)))
        out = [before]
        while out[-1] < end:
            d = out[-1] + SECOND
            out.append(min(float(self.obs.next_transit(self.sun, start=d)),
                           float(self.obs.next_antitransit(self.sun, start=d))))
        return out

    def event(self, a, b, rising):
        """The one rising (or setting) of the sun's centre in (a, b), where
        it is down (up) at a and up (down) at b: ephem's, narrowed by
        bisection on the apparent altitude."""
        lo, hi = a, b
        try:
            find = self.obs.next_rising if rising else self.obs.next_setting
            guess = float(find(self.sun, start=a, use_center=True))
            for width in (SECOND, 60 * SECOND):
                if a < guess - width and guess + width < b and \
                        self.up(guess - width) != rising and self.up(guess + width) == rising:
                    lo, hi = guess - width, guess + width
                    break
        except ephem.CircumpolarError:
            pass
        # Invariant: down (up) at lo, up (down) at hi.
        while hi - lo > BISECTION_WIDTH:
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                break
            if self.up(mid) == rising:
                hi = mid
            else:
                lo = mid
        return 0.5 * (lo + hi)


def sun_up_hours(lat, lon, start_unix, end_unix):
    site = Site(lat, lon)
    start, end = ephem_date(start_unix), ephem_date(end_unix)
    cuts = site.culminations(start, end)
    up = [site.up(d) for d in cuts]
    # Intervals with the sun up, over [cuts[0], cuts[-1]].
    intervals = []
    since = cuts[0] if up[0] else None
    for i in range(1, len(cuts)):
        if up[i] == up[i - 1]:
            continue
        e = site.event(cuts[i - 1], cuts[i], rising=up[i])
        if up[i]:
            since = e
        else:
            intervals.append((since, e))
            since = None
    if since is not None:
        intervals.append((since, cuts[-1]))
    days = sum(max(0.0, min(b, end) - max(a, start)) for a, b in intervals)
    return days * 24.0


def table():
    lines = [",".join(COLUMNS)]
    for name, lat, lon in SITES:
        for (y0, m0, d0), (y1, m1, d1) in PERIODS:
            t0, t1 = unix_of(y0, m0, d0, 0), unix_of(y1, m1, d1, 0)
            lines.append("%s,%.4f,%.4f,%s,%s,%.6f" % (
                name, lat, lon, utc_text(t0), utc_text(t1), sun_up_hours(lat, lon, t0, t1)))
    return lines


def header():
    return ["# Generated by scripts/make-sun-up-table.py with PyEphem %s: do not edit." % ephem.__version__,
            "# Observer at 0 m; up: the apparent elevation of the sun's centre, refracted for 1010 hPa and 10 C, above 0."]


def check(path):
    try:
        with open(path) as f:
            numbered = [(n, l.rstrip("\n")) for n, l in enumerate(f, start=1) if not l.startswith("#")]
        saved = [l for _, l in numbered]
    except OSError as e:
        sys.exit("make-sun-up-table --check: cannot read %s: %s" % (path, e))
    fresh = table()
    if len(saved) != len(fresh):
        sys.exit("make-sun-up-table --check: %s has %d lines, ephem's table %d: regenerate it"
                 % (path, len(saved), len(fresh)))
    if saved[0] != fresh[0]:
        sys.exit("make-sun-up-table --check: columns differ: %r, expected %r" % (saved[0], fresh[0]))
    for (n, a), b in zip(numbered[1:], fresh[1:]):
        fa, fb = a.split(","), b.split(",")
        same = len(fa) == len(fb) and fa[:5] == fb[:5] and all(
            abs(float(x) - float(y)) <= CHECK_TOLERANCE for x, y in zip(fa[5:], fb[5:]))
        if not same:
            sys.exit("make-sun-up-table --check: %s line %d is not ephem's output:\n  file:  %s\n  ephem: %s"
                     % (path, n, a, b))
    print("make-sun-up-table --check: %s: %d rows are PyEphem %s's output" % (path, len(fresh) - 1, ephem.__version__))


def main(argv):
    if len(argv) == 3 and argv[1] == "--check":
        check(argv[2])
    elif len(argv) == 2 and not argv[1].startswith("-"):
        with open(argv[1], "w") as f:
            f.write("\n".join(header() + table()) + "\n")
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main(sys.argv)
