/*
 * Decimal text <-> fixed point, exactly rounded, for the CLI, the daemon and
 * anything else that reads or writes numbers. Freestanding: no stdio, no
 * float, no heap.
 *
 * Parsing keeps the decimal fraction as a digit array and doubles it once per
 * fraction bit, so the result is the exact value rounded to nearest with ties
 * away from zero. Keeping TEXT_FRAC_DIGITS >= frac_bits + 1 digits is enough
 * even when more are given (see round_fraction()).
 */
#include "it2n.h"

#include <string.h>

/* Fraction digits kept. >= 33 is needed for Q32 (see round_fraction()). */
#define TEXT_FRAC_DIGITS 40
/* Integer digits accepted after leading zeros (limit checks come later). */
#define TEXT_INT_DIGITS 12
/* Exponents beyond this only ever mean 0 or out of range. */
#define TEXT_EXP_CAP 1000

typedef char text_frac_digits_fit[(TEXT_FRAC_DIGITS >= IT2N_PAR_FRAC + 1 && TEXT_FRAC_DIGITS >= IT2N_VAL_FRAC + 1 &&
                                   TEXT_FRAC_DIGITS >= IT2N_MEMB_FRAC + 1)
                                      ? 1
                                      : -1];

/* A parsed decimal: sign, integer part, first fraction digits, and whether
 * any non-zero digit lies beyond those kept. */
typedef struct text_dec {
    bool neg;
    uint64_t ipart;
    uint8_t frac[TEXT_FRAC_DIGITS];
    bool frac_nonzero; /* any non-zero fraction digit, kept or not */
} text_dec;

static bool is_digit(char c)
{
    return c >= '0' && c <= '9';
}

/*
 * Syntax: [+-] digits [. digits] [(e|E) [+-] digits], or [+-] . digits ...;
 * at least one mantissa digit. No spaces, no hex, no inf/nan.
 * Returns IT2N_OK, IT2N_ERR_INVAL or IT2N_ERR_RANGE (integer part too long).
 */
static int text_scan(const char *s, size_t len, text_dec *d)
{
    size_t k = 0;
    size_t mant_start, mant_end, dot = (size_t)-1;
    size_t ndigits = 0;
    long exp10 = 0;

    if (s == NULL || len == 0u) {
        return IT2N_ERR_INVAL;
    }
    memset(d, 0, sizeof(*d));
    if (s[k] == '+' || s[k] == '-') {
        d->neg = s[k] == '-';
        k++;
    }
    mant_start = k;
    for (; k < len; k++) {
        if (is_digit(s[k])) {
            ndigits++;
        } else if (s[k] == '.' && dot == (size_t)-1) {
            dot = k;
        } else {
            break;
        }
    }
    mant_end = k;
    if (ndigits == 0u) {
        return IT2N_ERR_INVAL;
    }
    if (dot == (size_t)-1) {
        dot = mant_end;
    }
    if (k < len && (s[k] == 'e' || s[k] == 'E')) {
        bool eneg = false;
        size_t edigits = 0;
        k++;
        if (k < len && (s[k] == '+' || s[k] == '-')) {
            eneg = s[k] == '-';
            k++;
        }
        for (; k < len && is_digit(s[k]); k++) {
            if (exp10 < TEXT_EXP_CAP) {
                exp10 = exp10 * 10 + (s[k] - '0');
            }
            edigits++;
        }
        if (edigits == 0u) {
            return IT2N_ERR_INVAL;
        }
        if (eneg) {
            exp10 = -exp10;
        }
    }
    if (k != len) {
        return IT2N_ERR_INVAL;
    }

    /*
     * Digit at mantissa index p (dot excluded) has decimal position
     * pos = (digits before the dot) - 1 - p + exp10: pos >= 0 is the integer
     * part (10^pos), pos < 0 the fraction digit -pos.
     */
    {
        long before_dot = (long)(dot - mant_start);
        long p = 0;
        size_t q;
        unsigned int_digits = 0;
        for (q = mant_start; q < mant_end; q++) {
            long pos;
            unsigned dig;
            if (q == dot) {
                continue;
            }
            dig = (unsigned)(s[q] - '0');
            pos = before_dot - 1 - p + exp10;
            p++;
            if (pos >= 0) {
                if (d->ipart == 0u && dig == 0u) {
                    continue; /* leading zero */
                }
                if (pos >= TEXT_INT_DIGITS || int_digits >= TEXT_INT_DIGITS) {
                    return IT2N_ERR_RANGE;
                }
                d->ipart = d->ipart * 10u + dig;
                int_digits++;
                /* Digits not written when the exponent shifts the mantissa
                 * left are zeros: scale at the last mantissa digit below. */
            } else {
                long fpos = -pos - 1;
                if (dig != 0u) {
                    d->frac_nonzero = true;
                }
                if (fpos < TEXT_FRAC_DIGITS) {
                    d->frac[fpos] = (uint8_t)dig;
                }
            }
        }
        /* Trailing implied zeros of the integer part ("12e3"). */
        {
            long last_pos = before_dot - 1 - (p - 1) + exp10;
            if (d->ipart != 0u && last_pos > 0) {
                long z;
                for (z = 0; z < last_pos; z++) {
                    if (int_digits >= TEXT_INT_DIGITS) {
                        return IT2N_ERR_RANGE;
                    }
                    d->ipart *= 10u;
                    int_digits++;
                }
            }
        }
    }
    return IT2N_OK;
}

/*
 * round(frac * 2^bits), frac = 0.d1 d2 ... (kept digits), ties up.
 *
 * Why truncating to N >= bits + 1 digits is exact: with T the kept digits,
 * T * 2^bits mod 10^N is a multiple of 2^bits, and so is 10^N / 2 (N > bits).
 * So the kept remainder is either >= one half or at least 2^bits / 10^N
 * below it, and the dropped tail adds less than 2^bits / 10^N: neither the
 * integer bits nor the rounding decision can change.
 */
static uint64_t round_fraction(const text_dec *d, unsigned bits)
{
    uint8_t f[TEXT_FRAC_DIGITS];
    uint64_t r = 0;
    unsigned b;
    memcpy(f, d->frac, sizeof(f));
    for (b = 0; b < bits; b++) {
        unsigned carry = 0;
        int k;
        for (k = TEXT_FRAC_DIGITS - 1; k >= 0; k--) {
            unsigned v = (unsigned)f[k] * 2u + carry;
            f[k] = (uint8_t)(v % 10u);
            carry = v / 10u;
        }
        r = (r << 1) | carry;
    }
    return r + (f[0] >= 5u ? 1u : 0u);
}

/* True when the exact value of d exceeds `limit` in magnitude. */
static bool text_exceeds(const text_dec *d, uint64_t limit)
{
    return d->ipart > limit || (d->ipart == limit && d->frac_nonzero);
}

/* Parse into raw / 2^frac, |value| <= limit; negatives only if allowed
 * (a negative zero is zero). Shared by values (Q24), memberships (Q30) and
 * parameters (Q32). */
static int text_parse(const char *s, size_t len, unsigned frac, uint64_t limit, bool allow_neg, int64_t *out)
{
    text_dec d;
    uint64_t mag;
    int rc;

    if (out == NULL) {
        return IT2N_ERR_INVAL;
    }
    rc = text_scan(s, len, &d);
    if (rc != IT2N_OK) {
        return rc;
    }
    if (text_exceeds(&d, limit) || (!allow_neg && d.neg && (d.ipart != 0u || d.frac_nonzero))) {
        return IT2N_ERR_RANGE;
    }
    mag = (d.ipart << frac) + round_fraction(&d, frac);
    *out = d.neg ? -(int64_t)mag : (int64_t)mag;
    return IT2N_OK;
}

int it2n_parse_val(const char *s, size_t len, it2n_val *out)
{
    return text_parse(s, len, IT2N_VAL_FRAC, (uint64_t)IT2N_COORD_LIMIT, true, out);
}

/* IT2N_COORD_LIMIT < 2^23: |raw| < 2^53 in Q30, no overflow. */
int it2n_parse_memb(const char *s, size_t len, it2n_val *out)
{
    return text_parse(s, len, IT2N_MEMB_FRAC, (uint64_t)IT2N_COORD_LIMIT, true, out);
}

int it2n_parse_par(const char *s, size_t len, it2n_par *out)
{
    return text_parse(s, len, IT2N_PAR_FRAC, 1u, false, out);
}

/* Format raw / 2^bits with `decimals` digits, rounded half away from zero. */
static int text_format(char *buf, size_t size, int64_t raw, unsigned bits, unsigned decimals)
{
    static const uint32_t pow10[10] = {1u,      10u,      100u,      1000u,      10000u,
                                       100000u, 1000000u, 10000000u, 100000000u, 1000000000u};
    char tmp[48]; /* sign + 20 integer digits + point + 9 decimals */
    size_t n = 0, k;
    uint64_t mag, ipart, frac, q;
    bool neg = raw < 0;

    if (buf == NULL || decimals > 9u) {
        return IT2N_ERR_INVAL;
    }
    mag = neg ? (uint64_t)0 - (uint64_t)raw : (uint64_t)raw;
    ipart = mag >> bits;
    frac = mag & (((uint64_t)1 << bits) - 1u);
    /* frac < 2^32 and 10^9 < 2^30: the product fits in 64 bits. */
    q = (frac * pow10[decimals] + ((uint64_t)1 << (bits - 1u))) >> bits;
    if (q >= pow10[decimals]) {
        q -= pow10[decimals];
        ipart++;
    }
    /* Digits, least significant first. */
    for (k = 0; k < decimals; k++) {
        tmp[n++] = (char)('0' + (char)(q % 10u));
        q /= 10u;
    }
    if (decimals > 0u) {
        tmp[n++] = '.';
    }
    do {
        tmp[n++] = (char)('0' + (char)(ipart % 10u));
        ipart /= 10u;
    } while (ipart != 0u);
    if (neg) {
        /* No "-0.000000": a minus sign only if a non-zero digit is shown. */
        bool nonzero = false;
        for (k = 0; k < n; k++) {
            if (tmp[k] >= '1' && tmp[k] <= '9') {
                nonzero = true;
            }
        }
        if (nonzero) {
            tmp[n++] = '-';
        }
    }
    if (size < n + 1u) {
        return IT2N_ERR_RANGE;
    }
    for (k = 0; k < n; k++) {
        buf[k] = tmp[n - 1u - k];
    }
    buf[n] = '\0';
    return (int)n;
}

int it2n_format_val(char *buf, size_t size, it2n_val v, unsigned decimals)
{
    return text_format(buf, size, v, IT2N_VAL_FRAC, decimals);
}

int it2n_format_par(char *buf, size_t size, it2n_par p, unsigned decimals)
{
    return text_format(buf, size, p, IT2N_PAR_FRAC, decimals);
}
