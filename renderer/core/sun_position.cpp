// NREL SPA (see sun_position.hpp), delta T, and RFC 3339 date-times.
#include "core/sun_position.hpp"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <iterator>

#include "core/request.hpp"

namespace umbra {
namespace {

constexpr double kPi = 3.14159265358979323846;
double rad(double deg) { return deg * (kPi / 180.0); }
double deg(double rad) { return rad * (180.0 / kPi); }
// x modulo 360 in [0, 360): fmod keeps the sign of x.
double wrap360(double x) {
  double r = std::fmod(x, 360.0);
  if (r < 0) r += 360.0;
  return r >= 360.0 ? 0.0 : r;  // -1e-18 + 360 rounds to 360
}

// ---- SPA's tables -------------------------------------------------------
// Table A4.2 (Earth's periodic terms, from VSOP87) and Table A4.3
// (nutation, from the IAU 1980 theory) of Reda & Andreas. The numbers were
// taken from pvlib-python's pvlib/spa.py (BSD-3-Clause; commit 6382338),
// which transcribes the paper, by a script rather than by hand; the row
// counts are the paper's (L0 64, L1 34, L2 20, L3 7, L4 3, L5 1, B0 5, B1 2,
// R0 40, R1 10, R2 6, R3 2, R4 1, nutation 63).

// One term A cos(B + C x): A in 1e-8 rad (or AU), B rad, C rad per
// Julian millennium.
struct PeriodicTerm {
  double a, b, c;
};
// Nutation: (a + b T) sin(arg) 0.0001" in longitude, (c + d T) cos(arg) in obliquity.
struct NutationCoefficients {
  double a, b, c, d;
};
// Multiples of the five fundamental arguments X0..X4 in arg.
struct NutationArgument {
  int y[5];
};

constexpr PeriodicTerm kL0[] = {
    {175347046.0, 0.0, 0.0},
    {3341656.0, 4.6692568, 6283.07585},
    {34894.0, 4.6261, 12566.1517},
    {3497.0, 2.7441, 5753.3849},
    {3418.0, 2.8289, 3.5231},
    {3136.0, 3.6277, 77713.7715},
    {2676.0, 4.4181, 7860.4194},
    {2343.0, 6.1352, 3930.2097},
    {1324.0, 0.7425, 11506.7698},
    {1273.0, 2.0371, 529.691},
    {1199.0, 1.1096, 1577.3435},
    {990.0, 5.233, 5884.927},
    {902.0, 2.045, 26.298},
    {857.0, 3.508, 398.149},
    {780.0, 1.179, 5223.694},
    {753.0, 2.533, 5507.553},
    {505.0, 4.583, 18849.228},
    {492.0, 4.205, 775.523},
    {357.0, 2.92, 0.067},
    {317.0, 5.849, 11790.629},
    {284.0, 1.899, 796.298},
    {271.0, 0.315, 10977.079},
    {243.0, 0.345, 5486.778},
    {206.0, 4.806, 2544.314},
    {205.0, 1.869, 5573.143},
    {202.0, 2.458, 6069.777},
    {156.0, 0.833, 213.299},
    {132.0, 3.411, 2942.463},
    {126.0, 1.083, 20.775},
    {115.0, 0.645, 0.98},
    {103.0, 0.636, 4694.003},
    {102.0, 0.976, 15720.839},
    {102.0, 4.267, 7.114},
    {99.0, 6.21, 2146.17},
    {98.0, 0.68, 155.42},
    {86.0, 5.98, 161000.69},
    {85.0, 1.3, 6275.96},
    {85.0, 3.67, 71430.7},
    {80.0, 1.81, 17260.15},
    {79.0, 3.04, 12036.46},
    {75.0, 1.76, 5088.63},
    {74.0, 3.5, 3154.69},
    {74.0, 4.68, 801.82},
    {70.0, 0.83, 9437.76},
    {62.0, 3.98, 8827.39},
    {61.0, 1.82, 7084.9},
    {57.0, 2.78, 6286.6},
    {56.0, 4.39, 14143.5},
    {56.0, 3.47, 6279.55},
    {52.0, 0.19, 12139.55},
    {52.0, 1.33, 1748.02},
    {51.0, 0.28, 5856.48},
    {49.0, 0.49, 1194.45},
    {41.0, 5.37, 8429.24},
    {41.0, 2.4, 19651.05},
    {39.0, 6.17, 10447.39},
    {37.0, 6.04, 10213.29},
    {37.0, 2.57, 1059.38},
    {36.0, 1.71, 2352.87},
    {36.0, 1.78, 6812.77},
    {33.0, 0.59, 17789.85},
    {30.0, 0.44, 83996.85},
    {30.0, 2.74, 1349.87},
    {25.0, 3.16, 4690.48},
};
constexpr PeriodicTerm kL1[] = {
    {628331966747.0, 0.0, 0.0},
    {206059.0, 2.678235, 6283.07585},
    {4303.0, 2.6351, 12566.1517},
    {425.0, 1.59, 3.523},
    {119.0, 5.796, 26.298},
    {109.0, 2.966, 1577.344},
    {93.0, 2.59, 18849.23},
    {72.0, 1.14, 529.69},
    {68.0, 1.87, 398.15},
    {67.0, 4.41, 5507.55},
    {59.0, 2.89, 5223.69},
    {56.0, 2.17, 155.42},
    {45.0, 0.4, 796.3},
    {36.0, 0.47, 775.52},
    {29.0, 2.65, 7.11},
    {21.0, 5.34, 0.98},
    {19.0, 1.85, 5486.78},
    {19.0, 4.97, 213.3},
    {17.0, 2.99, 6275.96},
    {16.0, 0.03, 2544.31},
    {16.0, 1.43, 2146.17},
    {15.0, 1.21, 10977.08},
    {12.0, 2.83, 1748.02},
    {12.0, 3.26, 5088.63},
    {12.0, 5.27, 1194.45},
    {12.0, 2.08, 4694.0},
    {11.0, 0.77, 553.57},
    {10.0, 1.3, 6286.6},
    {10.0, 4.24, 1349.87},
    {9.0, 2.7, 242.73},
    {9.0, 5.64, 951.72},
    {8.0, 5.3, 2352.87},
    {6.0, 2.65, 9437.76},
    {6.0, 4.67, 4690.48},
};
constexpr PeriodicTerm kL2[] = {
    {52919.0, 0.0, 0.0},
    {8720.0, 1.0721, 6283.0758},
    {309.0, 0.867, 12566.152},
    {27.0, 0.05, 3.52},
    {16.0, 5.19, 26.3},
    {16.0, 3.68, 155.42},
    {10.0, 0.76, 18849.23},
    {9.0, 2.06, 77713.77},
    {7.0, 0.83, 775.52},
    {5.0, 4.66, 1577.34},
    {4.0, 1.03, 7.11},
    {4.0, 3.44, 5573.14},
    {3.0, 5.14, 796.3},
    {3.0, 6.05, 5507.55},
    {3.0, 1.19, 242.73},
    {3.0, 6.12, 529.69},
    {3.0, 0.31, 398.15},
    {3.0, 2.28, 553.57},
    {2.0, 4.38, 5223.69},
    {2.0, 3.75, 0.98},
};
constexpr PeriodicTerm kL3[] = {
    {289.0, 5.844, 6283.076},
    {35.0, 0.0, 0.0},
    {17.0, 5.49, 12566.15},
    {3.0, 5.2, 155.42},
    {1.0, 4.72, 3.52},
    {1.0, 5.3, 18849.23},
    {1.0, 5.97, 242.73},
};
constexpr PeriodicTerm kL4[] = {
    {114.0, 3.142, 0.0},
    {8.0, 4.13, 6283.08},
    {1.0, 3.84, 12566.15},
};
constexpr PeriodicTerm kL5[] = {
    {1.0, 3.14, 0.0},
};
constexpr PeriodicTerm kB0[] = {
    {280.0, 3.199, 84334.662},
    {102.0, 5.422, 5507.553},
    {80.0, 3.88, 5223.69},
    {44.0, 3.7, 2352.87},
    {32.0, 4.0, 1577.34},
};
constexpr PeriodicTerm kB1[] = {
    {9.0, 3.9, 5507.55},
    {6.0, 1.73, 5223.69},
};
constexpr PeriodicTerm kR0[] = {
    {100013989.0, 0.0, 0.0},
    {1670700.0, 3.0984635, 6283.07585},
    {13956.0, 3.05525, 12566.1517},
    {3084.0, 5.1985, 77713.7715},
    {1628.0, 1.1739, 5753.3849},
    {1576.0, 2.8469, 7860.4194},
    {925.0, 5.453, 11506.77},
    {542.0, 4.564, 3930.21},
    {472.0, 3.661, 5884.927},
    {346.0, 0.964, 5507.553},
    {329.0, 5.9, 5223.694},
    {307.0, 0.299, 5573.143},
    {243.0, 4.273, 11790.629},
    {212.0, 5.847, 1577.344},
    {186.0, 5.022, 10977.079},
    {175.0, 3.012, 18849.228},
    {110.0, 5.055, 5486.778},
    {98.0, 0.89, 6069.78},
    {86.0, 5.69, 15720.84},
    {86.0, 1.27, 161000.69},
    {65.0, 0.27, 17260.15},
    {63.0, 0.92, 529.69},
    {57.0, 2.01, 83996.85},
    {56.0, 5.24, 71430.7},
    {49.0, 3.25, 2544.31},
    {47.0, 2.58, 775.52},
    {45.0, 5.54, 9437.76},
    {43.0, 6.01, 6275.96},
    {39.0, 5.36, 4694.0},
    {38.0, 2.39, 8827.39},
    {37.0, 0.83, 19651.05},
    {37.0, 4.9, 12139.55},
    {36.0, 1.67, 12036.46},
    {35.0, 1.84, 2942.46},
    {33.0, 0.24, 7084.9},
    {32.0, 0.18, 5088.63},
    {32.0, 1.78, 398.15},
    {28.0, 1.21, 6286.6},
    {28.0, 1.9, 6279.55},
    {26.0, 4.59, 10447.39},
};
constexpr PeriodicTerm kR1[] = {
    {103019.0, 1.10749, 6283.07585},
    {1721.0, 1.0644, 12566.1517},
    {702.0, 3.142, 0.0},
    {32.0, 1.02, 18849.23},
    {31.0, 2.84, 5507.55},
    {25.0, 1.32, 5223.69},
    {18.0, 1.42, 1577.34},
    {10.0, 5.91, 10977.08},
    {9.0, 1.42, 6275.96},
    {9.0, 0.27, 5486.78},
};
constexpr PeriodicTerm kR2[] = {
    {4359.0, 5.7846, 6283.0758},
    {124.0, 5.579, 12566.152},
    {12.0, 3.14, 0.0},
    {9.0, 3.63, 77713.77},
    {6.0, 1.87, 5573.14},
    {3.0, 5.47, 18849.23},
};
constexpr PeriodicTerm kR3[] = {
    {145.0, 4.273, 6283.076},
    {7.0, 3.92, 12566.15},
};
constexpr PeriodicTerm kR4[] = {
    {4.0, 2.56, 6283.08},
};
constexpr NutationCoefficients kNutationCoefficients[] = {
    {-171996, -174.2, 92025, 8.9},
    {-13187, -1.6, 5736, -3.1},
    {-2274, -0.2, 977, -0.5},
    {2062, 0.2, -895, 0.5},
    {1426, -3.4, 54, -0.1},
    {712, 0.1, -7, 0},
    {-517, 1.2, 224, -0.6},
    {-386, -0.4, 200, 0},
    {-301, 0, 129, -0.1},
    {217, -0.5, -95, 0.3},
    {-158, 0, 0, 0},
    {129, 0.1, -70, 0},
    {123, 0, -53, 0},
    {63, 0, 0, 0},
    {63, 0.1, -33, 0},
    {-59, 0, 26, 0},
    {-58, -0.1, 32, 0},
    {-51, 0, 27, 0},
    {48, 0, 0, 0},
    {46, 0, -24, 0},
    {-38, 0, 16, 0},
    {-31, 0, 13, 0},
    {29, 0, 0, 0},
    {29, 0, -12, 0},
    {26, 0, 0, 0},
    {-22, 0, 0, 0},
    {21, 0, -10, 0},
    {17, -0.1, 0, 0},
    {16, 0, -8, 0},
    {-16, 0.1, 7, 0},
    {-15, 0, 9, 0},
    {-13, 0, 7, 0},
    {-12, 0, 6, 0},
    {11, 0, 0, 0},
    {-10, 0, 5, 0},
    {-8, 0, 3, 0},
    {7, 0, -3, 0},
    {-7, 0, 0, 0},
    {-7, 0, 3, 0},
    {-7, 0, 3, 0},
    {6, 0, 0, 0},
    {6, 0, -3, 0},
    {6, 0, -3, 0},
    {-6, 0, 3, 0},
    {-6, 0, 3, 0},
    {5, 0, 0, 0},
    {-5, 0, 3, 0},
    {-5, 0, 3, 0},
    {-5, 0, 3, 0},
    {4, 0, 0, 0},
    {4, 0, 0, 0},
    {4, 0, 0, 0},
    {-4, 0, 0, 0},
    {-4, 0, 0, 0},
    {-4, 0, 0, 0},
    {3, 0, 0, 0},
    {-3, 0, 0, 0},
    {-3, 0, 0, 0},
    {-3, 0, 0, 0},
    {-3, 0, 0, 0},
    {-3, 0, 0, 0},
    {-3, 0, 0, 0},
    {-3, 0, 0, 0},
};
constexpr NutationArgument kNutationArguments[] = {
    {0, 0, 0, 0, 1},
    {-2, 0, 0, 2, 2},
    {0, 0, 0, 2, 2},
    {0, 0, 0, 0, 2},
    {0, 1, 0, 0, 0},
    {0, 0, 1, 0, 0},
    {-2, 1, 0, 2, 2},
    {0, 0, 0, 2, 1},
    {0, 0, 1, 2, 2},
    {-2, -1, 0, 2, 2},
    {-2, 0, 1, 0, 0},
    {-2, 0, 0, 2, 1},
    {0, 0, -1, 2, 2},
    {2, 0, 0, 0, 0},
    {0, 0, 1, 0, 1},
    {2, 0, -1, 2, 2},
    {0, 0, -1, 0, 1},
    {0, 0, 1, 2, 1},
    {-2, 0, 2, 0, 0},
    {0, 0, -2, 2, 1},
    {2, 0, 0, 2, 2},
    {0, 0, 2, 2, 2},
    {0, 0, 2, 0, 0},
    {-2, 0, 1, 2, 2},
    {0, 0, 0, 2, 0},
    {-2, 0, 0, 2, 0},
    {0, 0, -1, 2, 1},
    {0, 2, 0, 0, 0},
    {2, 0, -1, 0, 1},
    {-2, 2, 0, 2, 2},
    {0, 1, 0, 0, 1},
    {-2, 0, 1, 0, 1},
    {0, -1, 0, 0, 1},
    {0, 0, 2, -2, 0},
    {2, 0, -1, 2, 1},
    {2, 0, 1, 2, 2},
    {0, 1, 0, 2, 2},
    {-2, 1, 1, 0, 0},
    {0, -1, 0, 2, 2},
    {2, 0, 0, 2, 1},
    {2, 0, 1, 0, 0},
    {-2, 0, 2, 2, 2},
    {-2, 0, 1, 2, 1},
    {2, 0, -2, 0, 1},
    {2, 0, 0, 0, 1},
    {0, -1, 1, 0, 0},
    {-2, -1, 0, 2, 1},
    {-2, 0, 0, 0, 1},
    {0, 0, 2, 2, 1},
    {-2, 0, 2, 0, 1},
    {-2, 1, 0, 2, 1},
    {0, 0, 1, -2, 0},
    {-1, 0, 1, 0, 0},
    {-2, 1, 0, 0, 0},
    {1, 0, 0, 0, 0},
    {0, 0, 1, 2, 0},
    {0, 0, -2, 2, 2},
    {-1, -1, 1, 0, 0},
    {0, 1, 1, 0, 0},
    {0, -1, 1, 2, 2},
    {2, -1, -1, 2, 2},
    {0, 0, 3, 2, 2},
    {2, -1, 0, 2, 2},
};

// sum over terms of A cos(B + C x)
template <std::size_t N>
double series(const PeriodicTerm (&terms)[N], double x) {
  double sum = 0.0;
  for (const PeriodicTerm& t : terms) sum += t.a * std::cos(t.b + t.c * x);
  return sum;
}

// L0 + L1 x + ... + Ln x^n, by Horner's rule; the series come in order.
template <typename... Sums>
double polynomial(double x, Sums... sums) {
  const double s[] = {sums...};
  double r = 0.0;
  for (std::size_t i = std::size(s); i-- > 0;) r = r * x + s[i];
  return r;
}

// Sun's semidiameter plus the refraction at the horizon (SPA's 0.26667 and
// its default atmos_refract 0.5667): below this true elevation no part of
// the disc is seen, and SPA adds no refraction.
constexpr double kSunsetElevationDeg = -(0.26667 + 0.5667);

}  // namespace

SunAngles solar_position(double latitude_deg, double longitude_deg, double unix_seconds, double delta_t_s,
                         const Atmosphere& atmosphere) {
  // 3.1: Julian day (UT) and Julian ephemeris day (TT). Unix day 0 is JD 2440587.5.
  const double jd = unix_seconds / 86400.0 + 2440587.5;
  const double jde = jd + delta_t_s / 86400.0;
  const double jc = (jd - 2451545.0) / 36525.0;    // Julian centuries from J2000 (UT)
  const double jce = (jde - 2451545.0) / 36525.0;  // ... (TT)
  const double jme = jce / 10.0;                   // Julian millennia (TT)

  // 3.2: Earth's heliocentric longitude, latitude (deg) and radius (AU).
  const double l_deg = wrap360(deg(polynomial(jme, series(kL0, jme), series(kL1, jme), series(kL2, jme),
                                              series(kL3, jme), series(kL4, jme), series(kL5, jme)) / 1e8));
  const double b_deg = deg(polynomial(jme, series(kB0, jme), series(kB1, jme)) / 1e8);
  const double r_au = polynomial(jme, series(kR0, jme), series(kR1, jme), series(kR2, jme), series(kR3, jme),
                                 series(kR4, jme)) / 1e8;

  // 3.3: the sun seen from the Earth's centre.
  const double theta = wrap360(l_deg + 180.0);
  const double beta = -b_deg;

  // 3.4: nutation in longitude and obliquity (deg).
  const double x[5] = {
      297.85036 + 445267.111480 * jce - 0.0019142 * jce * jce + jce * jce * jce / 189474.0,  // Moon's elongation
      357.52772 + 35999.050340 * jce - 0.0001603 * jce * jce - jce * jce * jce / 300000.0,   // Sun's anomaly
      134.96298 + 477198.867398 * jce + 0.0086972 * jce * jce + jce * jce * jce / 56250.0,   // Moon's anomaly
      93.27191 + 483202.017538 * jce - 0.0036825 * jce * jce + jce * jce * jce / 327270.0,   // Moon's latitude arg.
      125.04452 - 1934.136261 * jce + 0.0020708 * jce * jce + jce * jce * jce / 450000.0,    // Moon's node
  };
  double dpsi = 0.0, deps = 0.0;
  for (std::size_t i = 0; i < std::size(kNutationArguments); ++i) {
    double arg = 0.0;
    for (int j = 0; j < 5; ++j) arg += kNutationArguments[i].y[j] * x[j];
    arg = rad(arg);
    const NutationCoefficients& k = kNutationCoefficients[i];
    dpsi += (k.a + k.b * jce) * std::sin(arg);
    deps += (k.c + k.d * jce) * std::cos(arg);
  }
  dpsi /= 36000000.0;  // 0.0001 arc seconds -> degrees
  deps /= 36000000.0;

  // 3.5: true obliquity of the ecliptic (Laskar's polynomial, arc seconds).
  const double u = jme / 10.0;
  const double eps0 = polynomial(u, 84381.448, -4680.93, -1.55, 1999.25, -51.38, -249.67, -39.05, 7.12, 27.87,
                                 5.79, 2.45);
  const double eps = eps0 / 3600.0 + deps;

  // 3.6-3.7: aberration, then the apparent longitude.
  const double lambda = theta + dpsi - 20.4898 / (3600.0 * r_au);

  // 3.8: apparent sidereal time at Greenwich (deg).
  const double nu0 = wrap360(280.46061837 + 360.98564736629 * (jd - 2451545.0) + 0.000387933 * jc * jc -
                             jc * jc * jc / 38710000.0);
  const double nu = nu0 + dpsi * std::cos(rad(eps));

  // 3.9-3.10: geocentric right ascension and declination.
  const double lambda_r = rad(lambda), eps_r = rad(eps), beta_r = rad(beta);
  const double alpha = wrap360(deg(std::atan2(std::sin(lambda_r) * std::cos(eps_r) - std::tan(beta_r) * std::sin(eps_r),
                                              std::cos(lambda_r))));
  const double delta = deg(std::asin(std::sin(beta_r) * std::cos(eps_r) +
                                     std::cos(beta_r) * std::sin(eps_r) * std::sin(lambda_r)));

  // 3.11: local hour angle, westward from the meridian.
  const double h = wrap360(nu + longitude_deg - alpha);

  // 3.12: topocentric position (parallax of the observer off the Earth's centre).
  const double phi = rad(latitude_deg);
  const double xi = rad(8.794 / (3600.0 * r_au));  // equatorial horizontal parallax
  const double uu = std::atan(0.99664719 * std::tan(phi));
  const double xx = std::cos(uu) + atmosphere.elevation_m / 6378140.0 * std::cos(phi);
  const double yy = 0.99664719 * std::sin(uu) + atmosphere.elevation_m / 6378140.0 * std::sin(phi);
  const double h_r = rad(h), delta_r = rad(delta);
  const double dalpha = std::atan2(-xx * std::sin(xi) * std::sin(h_r), std::cos(delta_r) - xx * std::sin(xi) * std::cos(h_r));
  const double delta_p = std::atan2((std::sin(delta_r) - yy * std::sin(xi)) * std::cos(dalpha),
                                    std::cos(delta_r) - xx * std::sin(xi) * std::cos(h_r));
  const double h_p = h_r - dalpha;

  // 3.14: true elevation, then refraction as SPA applies it.
  const double e0 = deg(std::asin(std::sin(phi) * std::sin(delta_p) + std::cos(phi) * std::cos(delta_p) * std::cos(h_p)));
  double de = 0.0;
  if (e0 >= kSunsetElevationDeg)
    de = (atmosphere.pressure_hpa / 1010.0) * (283.0 / (273.0 + atmosphere.temperature_c)) * 1.02 /
         (60.0 * std::tan(rad(e0 + 10.3 / (e0 + 5.11))));

  // 3.15: azimuth, from north (SPA's astronomer's azimuth is from south).
  const double gamma = deg(std::atan2(std::sin(h_p), std::cos(h_p) * std::sin(phi) - std::tan(delta_p) * std::cos(phi)));
  return {wrap360(gamma + 180.0), e0 + de};
}

SunAngles solar_position(double latitude_deg, double longitude_deg, double unix_seconds) {
  return solar_position(latitude_deg, longitude_deg, unix_seconds, delta_t_seconds(decimal_year(unix_seconds)));
}

// ---- delta T ------------------------------------------------------------
namespace {

// The data of libastro's deltat.c in PyEphem 4.1.4 (Debian 12's
// python3-ephem), so that delta_t_seconds() is its model: the yearly values
// from the Astronomical Almanac and IERS reports, and Morrison & Stephenson's
// (2004) values per century. Only the numbers are taken; the interpolation
// below is Bessel's formula (Astronomical Almanac, page K11) written here.
// Observed TT - UT, hundredths of a second, at the start of each year 1620..2018.
constexpr short kDeltaTTable[] = {
    /* 1620 */ 12400, 11900, 11500, 11000, 10600, 10200, 9800, 9500, 9100, 8800,
    /* 1630 */ 8500, 8200, 7900, 7700, 7400, 7200, 7000, 6700, 6500, 6300,
    /* 1640 */ 6200, 6000, 5800, 5700, 5500, 5400, 5300, 5100, 5000, 4900,
    /* 1650 */ 4800, 4700, 4600, 4500, 4400, 4300, 4200, 4100, 4000, 3800,
    /* 1660 */ 3700, 3600, 3500, 3400, 3300, 3200, 3100, 3000, 2800, 2700,
    /* 1670 */ 2600, 2500, 2400, 2300, 2200, 2100, 2000, 1900, 1800, 1700,
    /* 1680 */ 1600, 1500, 1400, 1400, 1300, 1200, 1200, 1100, 1100, 1000,
    /* 1690 */ 1000, 1000, 900, 900, 900, 900, 900, 900, 900, 900,
    /* 1700 */ 900, 900, 900, 900, 900, 900, 900, 900, 1000, 1000,
    /* 1710 */ 1000, 1000, 1000, 1000, 1000, 1000, 1000, 1100, 1100, 1100,
    /* 1720 */ 1100, 1100, 1100, 1100, 1100, 1100, 1100, 1100, 1100, 1100,
    /* 1730 */ 1100, 1100, 1100, 1100, 1200, 1200, 1200, 1200, 1200, 1200,
    /* 1740 */ 1200, 1200, 1200, 1200, 1300, 1300, 1300, 1300, 1300, 1300,
    /* 1750 */ 1300, 1400, 1400, 1400, 1400, 1400, 1400, 1400, 1500, 1500,
    /* 1760 */ 1500, 1500, 1500, 1500, 1500, 1600, 1600, 1600, 1600, 1600,
    /* 1770 */ 1600, 1600, 1600, 1600, 1600, 1700, 1700, 1700, 1700, 1700,
    /* 1780 */ 1700, 1700, 1700, 1700, 1700, 1700, 1700, 1700, 1700, 1700,
    /* 1790 */ 1700, 1700, 1600, 1600, 1600, 1600, 1500, 1500, 1400, 1400,
    /* 1800 */ 1370, 1340, 1310, 1290, 1270, 1260, 1250, 1250, 1250, 1250,
    /* 1810 */ 1250, 1250, 1250, 1250, 1250, 1250, 1250, 1240, 1230, 1220,
    /* 1820 */ 1200, 1170, 1140, 1110, 1060, 1020, 960, 910, 860, 800,
    /* 1830 */ 750, 700, 660, 630, 600, 580, 570, 560, 560, 560,
    /* 1840 */ 570, 580, 590, 610, 620, 630, 650, 660, 680, 690,
    /* 1850 */ 710, 720, 730, 740, 750, 760, 770, 770, 780, 780,
    /* 1860 */ 788, 782, 754, 697, 640, 602, 541, 410, 292, 182,
    /* 1870 */ 161, 10, -102, -128, -269, -324, -364, -454, -471, -511,
    /* 1880 */ -540, -542, -520, -546, -546, -579, -563, -564, -580, -566,
    /* 1890 */ -587, -601, -619, -664, -644, -647, -609, -576, -466, -374,
    /* 1900 */ -272, -154, -2, 124, 264, 386, 537, 614, 775, 913,
    /* 1910 */ 1046, 1153, 1336, 1465, 1601, 1720, 1824, 1906, 2025, 2095,
    /* 1920 */ 2116, 2225, 2241, 2303, 2349, 2362, 2386, 2449, 2434, 2408,
    /* 1930 */ 2402, 2400, 2387, 2395, 2386, 2393, 2373, 2392, 2396, 2402,
    /* 1940 */ 2433, 2483, 2530, 2570, 2624, 2677, 2728, 2778, 2825, 2871,
    /* 1950 */ 2915, 2957, 2997, 3036, 3072, 3107, 3135, 3168, 3218, 3268,
    /* 1960 */ 3315, 3359, 3400, 3447, 3503, 3573, 3654, 3743, 3829, 3920,
    /* 1970 */ 4018, 4117, 4223, 4337, 4449, 4548, 4646, 4752, 4853, 4959,
    /* 1980 */ 5054, 5138, 5217, 5296, 5379, 5434, 5487, 5532, 5582, 5630,
    /* 1990 */ 5686, 5757, 5831, 5912, 5998, 6078, 6163, 6230, 6297, 6347,
    /* 2000 */ 6383, 6409, 6430, 6447, 6457, 6469, 6485, 6515, 6546, 6578,
    /* 2010 */ 6607, 6632, 6660, 6691, 6728, 6764, 6810, 6859, 6897,
};
constexpr short kMorrisonStephensonCenturies[] = {
    /* -1000 */ 25428, 23700, 22000, 21000, 19040, 17190, 15530, 14080, 12790, 11640,
    /* 0 */ 10580, 9600, 8640, 7680, 6700, 5710, 4740, 3810, 2960, 2200,
    /* 1000 */ 1570, 1090, 740, 490, 320, 200, 120, 9,
};

constexpr int kTableFirstYear = 1620;
constexpr int kTableSize = static_cast<int>(std::size(kDeltaTTable));
constexpr int kTableLastYear = kTableFirstYear + kTableSize - 1;  // 2018

// Morrison & Stephenson (2004): delta T far from the present, seconds.
double long_term_parabola(double year) {
  const double b = (year - 1820.0) / 100.0;
  return 32.0 * b * b - 20.0;
}

// Table value i in seconds, or nothing past either end.
bool table_at(int i, double* out) {
  if (i < 0 || i >= kTableSize) return false;
  *out = kDeltaTTable[i] / 100.0;
  return true;
}

// Bessel's interpolation between years i and i+1 at fraction p, with the
// differences the table has around them: up to the fourth, fewer within two
// years of the table's ends (libastro differs there by < 0.01 s).
double bessel(int i, double p) {
  double f[6] = {};  // f[k] = value at year i - 2 + k
  bool have[6];
  for (int k = 0; k < 6; ++k) have[k] = table_at(i - 2 + k, &f[k]);
  double ans = f[2] + p * (f[3] - f[2]);
  if (!have[1] || !have[4]) return ans;  // no second differences
  // Central second differences at years i and i+1.
  const double d2_i = f[3] - 2 * f[2] + f[1];
  const double d2_i1 = f[4] - 2 * f[3] + f[2];
  const double b2 = 0.25 * p * (p - 1.0);
  ans += b2 * (d2_i + d2_i1);
  // Third difference centred on i + 1/2 (from years i-1..i+2 as well).
  const double d3 = d2_i1 - d2_i;
  const double b3 = 2.0 * b2 / 3.0;
  ans += (p - 0.5) * b3 * d3;
  if (!have[0] || !have[5]) return ans;
  // Fourth differences at i and i+1.
  const double d2_im1 = f[2] - 2 * f[1] + f[0];
  const double d2_i2 = f[5] - 2 * f[4] + f[3];
  const double d4_i = d2_i1 - 2 * d2_i + d2_im1;
  const double d4_i1 = d2_i2 - 2 * d2_i1 + d2_i;
  const double b4 = 0.125 * b3 * (p + 1.0) * (p - 2.0);
  ans += b4 * (d4_i + d4_i1);
  return ans;
}

}  // namespace

double delta_t_seconds(double y) {
  if (std::isnan(y)) return y;
  if (y > kTableLastYear) {
    const double end = kTableLastYear + 100.0;
    if (y > end) return long_term_parabola(y);
    // A cubic in p = y - 2018 with a(0) = last value, a'(0) = slope over the
    // last ten years, a(100) and a'(100) = the parabola's.
    const double a = kDeltaTTable[kTableSize - 1] / 100.0;
    const double b = (kDeltaTTable[kTableSize - 1] - kDeltaTTable[kTableSize - 11]) / 1000.0;
    const double m0 = long_term_parabola(end);
    const double m1 = 0.64 * (end - 1820.0) / 100.0;  // the parabola's slope, s/year
    const double d = 2.0e-6 * (50.0 * (m1 + b) - m0 + a);
    const double c = 1.0e-4 * (m0 - a - 100.0 * b - 1.0e6 * d);
    const double p = y - kTableLastYear;
    return a + p * (b + p * (c + p * d));
  }
  if (y < 1700.0) {
    if (y <= -1000.0) return long_term_parabola(y);
    const int i = static_cast<int>(std::floor((y + 1000.0) / 100.0));
    const double start = -1000.0 + 100.0 * i;
    const double v0 = kMorrisonStephensonCenturies[i];
    const double v1 = kMorrisonStephensonCenturies[i + 1];
    return v0 + (y - start) / 100.0 * (v1 - v0);
  }
  const double fy = std::floor(y);
  return bessel(static_cast<int>(fy) - kTableFirstYear, y - fy);
}

// ---- calendar -----------------------------------------------------------
namespace {

// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's
// days_from_civil: exact for any year in 64 bits).
std::int64_t days_from_civil(std::int64_t y, int m, int d) {
  y -= m <= 2;
  const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
  const std::int64_t yoe = y - era * 400;
  const std::int64_t doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const std::int64_t doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + doe - 719468;
}

struct Civil {
  std::int64_t y;
  int m, d;
};
Civil civil_from_days(std::int64_t z) {
  z += 719468;
  const std::int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const std::int64_t doe = z - era * 146097;
  const std::int64_t yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const std::int64_t doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const std::int64_t mp = (5 * doy + 2) / 153;
  const int d = static_cast<int>(doy - (153 * mp + 2) / 5 + 1);
  const int m = static_cast<int>(mp < 10 ? mp + 3 : mp - 9);
  return {yoe + era * 400 + (m <= 2), m, d};
}

bool is_leap(std::int64_t y) { return (y % 4 == 0 && y % 100 != 0) || y % 400 == 0; }
int days_in_month(std::int64_t y, int m) {
  static constexpr int kDays[] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  return m == 2 && is_leap(y) ? 29 : kDays[m - 1];
}

// Far enough for any year a double's seconds can tell apart, small enough
// that int64 day arithmetic cannot overflow.
constexpr double kMaxAbsSeconds = 1e17;

}  // namespace

double decimal_year(double unix_seconds) {
  if (!std::isfinite(unix_seconds) || std::fabs(unix_seconds) > kMaxAbsSeconds) return unix_seconds;
  const Civil c = civil_from_days(static_cast<std::int64_t>(std::floor(unix_seconds / 86400.0)));
  const double start = days_from_civil(c.y, 1, 1) * 86400.0;
  const double next = days_from_civil(c.y + 1, 1, 1) * 86400.0;
  return static_cast<double>(c.y) + (unix_seconds - start) / (next - start);
}

// ---- RFC 3339 -----------------------------------------------------------
namespace {

std::string describe(char c) {
  if (c >= 0x21 && c <= 0x7e) return std::string("'") + c + "'";
  if (c == ' ') return "a space";
  char buf[16];
  std::snprintf(buf, sizeof buf, "byte 0x%02x", static_cast<unsigned char>(c));
  return buf;
}

class Reader {
 public:
  explicit Reader(std::string_view text) : text_(text) {}
  bool fail(std::string* why, const std::string& reason) {
    if (why) *why = reason;
    return false;
  }
  // "character N" is 1-based, as people count.
  std::string at() const { return "at character " + std::to_string(pos_ + 1); }
  bool done() const { return pos_ >= text_.size(); }
  char peek() const { return text_[pos_]; }
  // Exactly n digits, for the field `what`.
  bool digits(int n, const char* what, int* out, std::string* why) {
    int v = 0;
    for (int i = 0; i < n; ++i) {
      if (done())
        return fail(why, std::string("text ends in the ") + what + ": expected " + std::to_string(n) + " digits");
      const char c = peek();
      if (c < '0' || c > '9')
        return fail(why, "expected a digit of the " + std::string(what) + " " + at() + ", found " + describe(c));
      v = v * 10 + (c - '0');
      ++pos_;
    }
    *out = v;
    return true;
  }
  // One of the characters of `set`; `name` says what it is for.
  bool expect(const char* set, const char* name, std::string* why, char* got = nullptr) {
    if (done()) return fail(why, std::string("text ends where ") + name + " was expected");
    const char c = peek();
    for (const char* s = set; *s; ++s)
      if (c == *s) {
        ++pos_;
        if (got) *got = c;
        return true;
      }
    return fail(why, std::string("expected ") + name + " " + at() + ", found " + describe(c));
  }
  std::size_t pos() const { return pos_; }
  void advance() { ++pos_; }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
};

}  // namespace

std::optional<double> parse_utc(std::string_view text, std::string* why) {
  if (text.empty()) {
    if (why) *why = "empty: expected a date-time such as 2026-12-21T14:00:00Z";
    return std::nullopt;
  }
  Reader r(text);
  int year, month, day, hour, minute, second;
  if (!r.digits(4, "year", &year, why) || !r.expect("-", "'-'", why) || !r.digits(2, "month", &month, why) ||
      !r.expect("-", "'-'", why) || !r.digits(2, "day", &day, why) || !r.expect("Tt", "'T'", why) ||
      !r.digits(2, "hour", &hour, why) || !r.expect(":", "':'", why) || !r.digits(2, "minute", &minute, why) ||
      !r.expect(":", "':'", why) || !r.digits(2, "second", &second, why))
    return std::nullopt;
  const auto refuse = [&](const std::string& reason) -> std::optional<double> {
    if (why) *why = reason;
    return std::nullopt;
  };
  const auto two = [](int v) { return (v < 10 ? "0" : "") + std::to_string(v); };
  if (year < 1) return refuse("year 0000 is out of range (0001..9999)");
  if (month < 1 || month > 12) return refuse("month " + two(month) + " is out of range (01..12)");
  if (day < 1 || day > days_in_month(year, month)) {
    if (month == 2 && day == 29) return refuse(std::to_string(year) + " is not a leap year: February has 28 days");
    return refuse("day " + two(day) + " is out of range (01.." + std::to_string(days_in_month(year, month)) +
                  " in month " + two(month) + ")");
  }
  if (hour > 23) return refuse("hour " + two(hour) + " is out of range (00..23)");
  if (minute > 59) return refuse("minute " + two(minute) + " is out of range (00..59)");
  if (second == 60) return refuse("second 60 (a leap second) cannot be represented in unix time: use 59");
  if (second > 59) return refuse("second " + two(second) + " is out of range (00..59)");

  double fraction = 0.0;
  if (!r.done() && r.peek() == '.') {
    r.advance();
    int n = 0;
    double scale = 0.1;
    while (!r.done() && r.peek() >= '0' && r.peek() <= '9') {
      if (n < 9) fraction += (r.peek() - '0') * scale;  // past 1 ns: ignored
      scale /= 10.0;
      ++n;
      r.advance();
    }
    if (n == 0) {
      if (r.done()) return refuse("text ends after '.': expected fraction digits");
      return refuse("expected a digit after '.' " + r.at() + ", found " + describe(r.peek()));
    }
  }

  if (r.done()) return refuse("no time zone: end with Z or +hh:mm");
  int offset_minutes = 0;
  char zone = 0;
  if (!r.expect("Zz+-", "a time zone (Z, +hh:mm or -hh:mm)", why, &zone)) return std::nullopt;
  if (zone == '+' || zone == '-') {
    int oh, om;
    if (!r.digits(2, "offset's hours", &oh, why) || !r.expect(":", "':'", why) ||
        !r.digits(2, "offset's minutes", &om, why))
      return std::nullopt;
    if (oh > 23) return refuse("offset hours " + two(oh) + " are out of range (00..23)");
    if (om > 59) return refuse("offset minutes " + two(om) + " are out of range (00..59)");
    offset_minutes = (zone == '-' ? -1 : 1) * (oh * 60 + om);
  }
  if (!r.done())
    return refuse("unexpected " + describe(r.peek()) + " " + r.at() + " after the time zone");

  const std::int64_t days = days_from_civil(year, month, day);
  const std::int64_t whole = days * 86400 + hour * 3600 + minute * 60 + second - offset_minutes * 60;
  return static_cast<double>(whole) + fraction;
}

std::string format_utc(double unix_seconds) {
  if (!std::isfinite(unix_seconds)) return "";
  double s = std::floor(unix_seconds);
  if (std::fabs(s) > kMaxAbsSeconds) s = std::copysign(kMaxAbsSeconds, s);
  const std::int64_t whole = static_cast<std::int64_t>(s);
  std::int64_t days = whole / 86400, rem = whole % 86400;
  if (rem < 0) {
    rem += 86400;
    --days;
  }
  const Civil c = civil_from_days(days);
  char buf[64];
  const char* year_format = c.y < 0 ? "%05lld" : c.y > 9999 ? "+%lld" : "%04lld";
  int n = std::snprintf(buf, sizeof buf, year_format, static_cast<long long>(c.y));
  std::snprintf(buf + n, sizeof buf - n, "-%02d-%02dT%02d:%02d:%02dZ", c.m, c.d, static_cast<int>(rem / 3600),
                static_cast<int>(rem / 60 % 60), static_cast<int>(rem % 60));
  return buf;
}

std::string format_sun_angles(const SunAngles& sun) {
  // + 0.0 turns a rounded -0.0 into +0.0.
  const auto four_places = [](double v) { return std::round(v * 1e4) / 1e4 + 0.0; };
  double azimuth = four_places(sun.azimuth_deg);
  if (azimuth >= 360.0) azimuth -= 360.0;
  char buffer[96];
  std::snprintf(buffer, sizeof buffer, "azimuth_deg=%.4f; elevation_deg=%.4f", azimuth, four_places(sun.elevation_deg));
  return buffer;
}

SunAngles sun_at(const SunClock& clock, double time) {
  return solar_position(clock.latitude_deg, clock.longitude_deg, clock.utc_unix_s + time);
}

}  // namespace umbra
