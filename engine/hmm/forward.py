"""Scaled forward algorithm (Rabiner 1989) for the flattened hierarchical HMM (spec B2.5).

Alpha is renormalised every step (sum = 1) and the log of each normaliser accumulated, so the log-likelihood
never underflows however long the sequence is.
"""
from __future__ import annotations

import numpy as np
from scipy import sparse


def forward(log_emissions: np.ndarray, transitions: sparse.csr_matrix, initial: np.ndarray) -> tuple[np.ndarray, float]:
    """log_emissions (T, S) log b_j(y_t); transitions (S, S) row-stochastic a_ij; initial (S,) pi.
    Returns (normalised alpha_T (S,), log P(y_1..T))."""
    transposed = transitions.T.tocsr()
    log_likelihood = 0.0
    alpha = initial
    for t, log_b in enumerate(log_emissions):
        shift = log_b.max()
        pred = alpha if t == 0 else transposed @ alpha
        alpha = pred * np.exp(log_b - shift)
        total = alpha.sum()
        if total <= 0.0:   # observation impossible under every predicted state: restart from the emissions alone
            alpha = np.exp(log_b - shift)
            total = alpha.sum()
        alpha = alpha / total
        log_likelihood += np.log(total) + shift
    return alpha, log_likelihood


def chain_forward(log_emissions: np.ndarray, p_self: float, p_next: float, p_skip: float) -> tuple[np.ndarray, np.ndarray]:
    """Forward pass on many independent left-to-right chains at once (reactive-interpolation scoring).

    log_emissions (T, C, L): C chains of L states. Mass that would run past the last state stays there.
    Starts uniformly over each chain. Returns (alpha_T (C, L), log-likelihood per chain (C,))."""
    steps, chains, length = log_emissions.shape
    alpha = np.full((chains, length), 1.0 / length)
    loglik = np.zeros(chains)
    for t in range(steps):
        if t:
            pred = p_self * alpha
            pred[:, 1:] += p_next * alpha[:, :-1]
            pred[:, -1] += p_next * alpha[:, -1]
            pred[:, 2:] += p_skip * alpha[:, :-2]
            pred[:, -1] += p_skip * alpha[:, -2:].sum(axis=1) if length > 1 else p_skip * alpha[:, -1]
            alpha = pred
        shift = log_emissions[t].max(axis=1, keepdims=True)
        alpha = alpha * np.exp(log_emissions[t] - shift)
        total = alpha.sum(axis=1, keepdims=True)
        alpha = alpha / total
        loglik += np.log(total[:, 0]) + shift[:, 0]
    return alpha, loglik
