"""Draws per second and ESS per second: the project's MH kernel against emcee.

Both sample the same surrogate posterior: the GP of log L fitted to 300 Sobol points
of the 7-D correlated Gaussian test target (q = 7), evaluated through the same
batched torch potential (emcee with ``vectorize=True`` gets it as a numpy function).

- ``rwm-vectorized-C``: :class:`susp_bo.calibration.mcmc.RandomWalkMetropolis` with C
  chains in one kernel step, plain torch loop (``run_vectorized``);
- ``rwm-pyro-C``: the same kernel through ``pyro.infer.MCMC``;
- ``emcee-W``: emcee's affine-invariant ensemble (stretch move) with W walkers.

Draws = chains (walkers) x all steps, warm-up included; ESS = the smallest over the
7 parameters of Pyro's ``effective_sample_size`` on the kept draws (walkers taken as
chains; emcee's own integrated-autocorrelation ESS is printed too); times are wall
clock for the whole run. Ratios are against emcee with 32 walkers, measured in the
same run.

    python benchmarks/mcmc_speed.py            # torch with 1 thread (see --threads)
"""

from __future__ import annotations

import argparse
import sys
import time

import emcee
import numpy as np
import pyro.ops.stats as pyro_stats
import torch

from susp_bo.calibration.design import space_filling_design, to_unit
from susp_bo.calibration.loop_step import torch_threads
from susp_bo.calibration.mcmc import RandomWalkMetropolis, run_pyro, run_vectorized
from susp_bo.calibration.sampling import initial_positions, surrogate_potential
from susp_bo.calibration.surrogate import SurrogateSettings
from susp_bo.calibration.surrogate_fit import fit_surrogate
from susp_bo.calibration.test_functions import correlated_gaussian_7d


def _ess(draws: torch.Tensor) -> float:
    """Smallest ESS over parameters, draws (chains x n x q)."""
    return float(pyro_stats.effective_sample_size(draws, chain_dim=0, sample_dim=1).min())


def main(argv: list[str] | None = None) -> int:
    """Runs the comparison and prints a table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--threads", type=int, default=1, help="torch intra-op threads")
    parser.add_argument("--warmup", type=int, default=1000)
    parser.add_argument("--samples", type=int, default=3000)
    parser.add_argument("--chains", nargs="+", type=int, default=[64, 256, 1024])
    parser.add_argument("--walkers", nargs="+", type=int, default=[32, 64])
    args = parser.parse_args(argv)

    target = correlated_gaussian_7d()
    x = space_filling_design(300, target.bounds, seed=0)
    y = target(x)
    rows: list[tuple[str, float, float, float, str]] = []
    with torch_threads(args.threads), torch.no_grad():
        surrogate = fit_surrogate(to_unit(x, target.bounds), y, SurrogateSettings(), seed=0)
        potential = surrogate_potential(surrogate)
        q = surrogate.dim
        print(
            f"surrogate: n = {x.shape[0]}, q = {q}, warping {surrogate.warping.kind}; "
            f"torch threads {torch.get_num_threads()}",
            flush=True,
        )
        steps = args.warmup + args.samples
        for chains in args.chains:
            for backend in ("vectorized", "pyro"):
                if backend == "pyro" and chains != args.chains[0]:
                    continue
                starts = initial_positions(to_unit(x, target.bounds), y, chains, 1)
                kernel = RandomWalkMetropolis(
                    potential, starts, seed=1, proposal_cov=0.03**2 * torch.eye(q)
                )
                t0 = time.perf_counter()
                if backend == "vectorized":
                    draws = run_vectorized(kernel, args.samples, args.warmup)
                else:
                    draws = run_pyro(kernel, args.samples, args.warmup)
                dt = time.perf_counter() - t0
                ess = _ess(draws)
                acc = kernel.diagnostics()["acceptance rate"]
                rows.append(
                    (
                        f"rwm-{backend}-{chains}",
                        chains * steps / dt,
                        ess / dt,
                        dt,
                        f"acceptance {acc:.3f}, ESS {ess:.0f}",
                    )
                )
                print(f"{rows[-1][0]:24s} done", flush=True)

        def log_prob(u: np.ndarray) -> np.ndarray:
            return -potential(torch.as_tensor(u, dtype=torch.float64)).numpy()

        for walkers in args.walkers:
            starts = initial_positions(to_unit(x, target.bounds), y, walkers, 2).numpy()
            sampler = emcee.EnsembleSampler(walkers, q, log_prob, vectorize=True)
            sampler.random_state = np.random.RandomState(2).get_state()
            t0 = time.perf_counter()
            state = sampler.run_mcmc(starts, args.warmup)
            sampler.reset()
            sampler.run_mcmc(state, args.samples)
            dt = time.perf_counter() - t0
            chain = sampler.get_chain()  # n x walkers x q
            ess = _ess(torch.as_tensor(chain).transpose(0, 1))
            tau = emcee.autocorr.integrated_time(chain, quiet=True)
            ess_emcee = float(walkers * args.samples / np.max(tau))
            acc = float(np.mean(sampler.acceptance_fraction))
            rows.append(
                (
                    f"emcee-{walkers}",
                    walkers * steps / dt,
                    ess / dt,
                    dt,
                    f"acceptance {acc:.3f}, ESS {ess:.0f} (emcee tau-based ESS {ess_emcee:.0f})",
                )
            )
            print(f"{rows[-1][0]:24s} done", flush=True)

    ref = next(r for r in rows if r[0].startswith("emcee"))
    print(
        f"\n{'sampler':24s} {'draws/s':>12s} {'ESS/s':>10s} {'time s':>8s} "
        f"{'draws/s ratio':>13s} {'ESS/s ratio':>11s}  notes"
    )
    for name, dps, esps, dt, note in rows:
        print(
            f"{name:24s} {dps:12.0f} {esps:10.1f} {dt:8.2f} {dps / ref[1]:13.1f} "
            f"{esps / ref[2]:11.1f}  {note}"
        )
    print(f"(ratios against {ref[0]}; targets: >= 100000 draws/s, ESS/s >= emcee's)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
