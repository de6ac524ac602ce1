#!/usr/bin/python3
"""Writes tests/data/sun_positions.csv: the sun's azimuth and elevation by
PyEphem (Debian's python3-ephem), the independent reference for
renderer/core/sun_position.cpp (tests/test_sun_position.cpp).

    scripts/make-sun-table.py OUT.csv        write the table
    scripts/make-sun-table.py --check CSV    recompute it and compare (a ctest)

PyEphem's theory of the sun is built in (libastro: VSOP87), so this needs no
data download. The rows are a fixed, deterministic spread: years 1950..2100
(both ends included), latitudes from pole to pole (the poles themselves
too), longitudes on both sides of the date line and of Greenwich, the
solstices and equinoxes and other days, and every hour of the day, so that
elevations run from the nadir side to near the zenith.

Columns (angles in degrees):
  unix_seconds      the instant, UTC seconds since 1970-01-01T00:00:00Z
  utc               the same, as text (whole seconds)
  latitude, longitude   of an observer at elevation 0 m
  delta_t_s         TT - UT that ephem used, seconds (ephem.delta_t)
  azimuth           clockwise from north, [0, 360)
  elevation         apparent: refracted for 1010 hPa, 10 C (horizon 0)
  true_elevation    the same position unrefracted (pressure 0)
"""
import datetime
import math
import sys

try:
    import ephem
except ImportError:
    sys.exit("make-sun-table: PyEphem is missing: install Debian's python3-ephem "
             "(bash scripts/install-deps.sh) and run this with /usr/bin/python3")

COLUMNS = ["unix_seconds", "utc", "latitude", "longitude", "delta_t_s",
           "azimuth", "elevation", "true_elevation"]
# Tolerance of --check, degrees and seconds: the same ephem computes the same
# numbers; the slack only absorbs a different libm's last bits.
CHECK_TOLERANCE = 1e-6

LATITUDES = [-90.0, -89.9, -78.2, -66.56, -55.0, -45.0, -33.87, -23.44, -12.0, -0.5,
             0.0, 5.0, 16.0, 23.44, 35.0, 48.85, 60.0, 66.56, 71.0, 89.9, 90.0]
LONGITUDES = [-179.9, -150.0, -105.1786, -60.0, -2.0, 0.0, 2.35, 45.0, 100.0,
              151.21, 179.9]
YEARS = list(range(1950, 2101, 5)) + [1951, 1987, 2016, 2017, 2018, 2019, 2026, 2099, 2100]
# (month, day): equinoxes and solstices, and days between.
DAYS = [(3, 20), (6, 21), (9, 22), (12, 21), (1, 3), (2, 14), (4, 30), (5, 15),
        (7, 4), (8, 8), (10, 31), (11, 11)]


def lcg(seed):
    """A fixed pseudo-random sequence (not Python's random: the table must
    not change with the Python version)."""
    state = seed
    while True:
        state = (state * 6364136223846793005 + 1442695040888963407) % 2**64
        yield state >> 11


def unix_of(year, month, day, seconds_of_day):
    # Days from 1970-01-01 (proleptic Gregorian), H. Hinnant's days_from_civil.
    y = year - (month <= 2)
    era = y // 400
    yoe = y - era * 400
    doy = (153 * (month + (-3 if month > 2 else 9)) + 2) // 5 + day - 1
    doe = yoe * 365 + yoe // 4 - yoe // 100 + doy
    return (era * 146097 + doe - 719468) * 86400 + seconds_of_day


def instants():
    """(unix_seconds, latitude, longitude), about 4000 of them."""
    rnd = lcg(15)
    rows = []
    for lat in LATITUDES:
        for lon in LONGITUDES:
            # Every hour of the day once per place, each on a different
            # year and day, at a pseudo-random minute and second.
            for hour in range(24):
                year = YEARS[next(rnd) % len(YEARS)]
                month, day = DAYS[next(rnd) % len(DAYS)]
                sec = hour * 3600 + next(rnd) % 3600
                rows.append((unix_of(year, month, day, sec), lat, lon))
    # Both ends of the range, at a few places.
    for (y, m, d) in [(1950, 1, 1), (2100, 12, 31)]:
        for lat, lon in [(48.85, 2.35), (-33.87, 151.21), (0.0, 179.9), (0.0, -179.9)]:
            for hour in range(0, 24, 3):
                rows.append((unix_of(y, m, d, hour * 3600), lat, lon))
    # Near the zenith: the subsolar latitude at local noon (the sun crosses
    # the meridian within ~16 min of 12:00 local mean time).
    for (y, m, d, lat) in [(2026, 6, 21, 23.44), (2026, 12, 21, -23.44), (2000, 3, 20, 0.0),
                           (1977, 9, 23, 0.0), (2088, 5, 1, 15.0)]:
        for lon in [-179.9, 0.0, 179.9]:
            for minutes in range(-20, 21, 2):
                noon = 12 * 3600 - lon / 15.0 * 3600
                rows.append((unix_of(y, m, d, 0) + round(noon) + minutes * 60, lat, lon))
    # The example.
    rows.append((unix_of(2026, 12, 21, 14 * 3600), 48.85, 2.35))
    return rows


def utc_text(t):
    d = datetime.datetime(1970, 1, 1) + datetime.timedelta(seconds=t)
    return d.strftime("%Y-%m-%dT%H:%M:%SZ")


def table():
    obs = ephem.Observer()
    obs.elevation = 0.0
    obs.temp = 10.0
    obs.horizon = 0.0
    lines = [",".join(COLUMNS)]
    for t, lat, lon in instants():
        obs.lat = math.radians(lat)
        obs.lon = math.radians(lon)
        # ephem's dates are days since 1899-12-31T12:00Z (UT); 1970 is 25567.5.
        obs.date = ephem.Date(t / 86400.0 + 25567.5)
        obs.pressure = 1010.0
        sun = ephem.Sun(obs)
        az, alt = math.degrees(sun.az), math.degrees(sun.alt)
        obs.pressure = 0.0
        true_alt = math.degrees(ephem.Sun(obs).alt)
        lines.append("%d,%s,%.4f,%.4f,%.4f,%.7f,%.7f,%.7f" % (
            t, utc_text(t), lat, lon, ephem.delta_t(obs.date), az, alt, true_alt))
    return lines


def header():
    return ["# Generated by scripts/make-sun-table.py with PyEphem %s: do not edit." % ephem.__version__,
            "# Observer at 0 m; elevation refracted for 1010 hPa and 10 C, true_elevation unrefracted."]


def check(path):
    try:
        with open(path) as f:
            numbered = [(n, l.rstrip("\n")) for n, l in enumerate(f, start=1) if not l.startswith("#")]
        saved = [l for _, l in numbered]
    except OSError as e:
        sys.exit("make-sun-table --check: cannot read %s: %s" % (path, e))
    fresh = table()
    if len(saved) != len(fresh):
        sys.exit("make-sun-table --check: %s has %d lines, ephem's table %d: regenerate it"
                 % (path, len(saved), len(fresh)))
    if saved[0] != fresh[0]:
        sys.exit("make-sun-table --check: columns differ: %r, expected %r" % (saved[0], fresh[0]))
    for (n, a), b in zip(numbered[1:], fresh[1:]):
        fa, fb = a.split(","), b.split(",")
        same = len(fa) == len(fb) and fa[:4] == fb[:4] and all(
            abs(float(x) - float(y)) <= CHECK_TOLERANCE for x, y in zip(fa[4:], fb[4:]))
        if not same:
            sys.exit("make-sun-table --check: %s line %d is not ephem's output:\n  file:  %s\n  ephem: %s"
                     % (path, n, a, b))
    print("make-sun-table --check: %s: %d rows are PyEphem %s's output" % (path, len(fresh) - 1, ephem.__version__))


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
