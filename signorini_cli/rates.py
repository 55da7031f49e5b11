"""Observed convergence rates from the measured h."""
import math


def observed(h, errors, valid):
    """Rates log(e_{k-1}/e_k)/log(h_{k-1}/h_k) against the previous valid level; None where undefined."""
    rates, previous = [], None
    for k, (h_k, e_k, ok) in enumerate(zip(h, errors, valid)):
        usable = ok and e_k is not None and e_k > 0
        if usable and previous is not None and h[previous] != h_k:
            rates.append(math.log(errors[previous] / e_k) / math.log(h[previous] / h_k))
        else:
            rates.append(None)
        previous = k if usable else previous
    return rates
