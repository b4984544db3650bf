"""Train a diffusion policy on a dataset (reference example 03).

    python examples/03_train.py --dataset-path data/pick_cube_demos_mimic.hdf5 --output-dir outputs/pick_cube
"""

from __future__ import annotations

import argparse

from newton_lab.policies import Policy


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--task", default="GalbotG1-PickCube-v0", help="checked against the dataset's task")
    p.add_argument("--dataset-path", default="data/pick_cube_demos_mimic.hdf5")
    p.add_argument("--output-dir", default="outputs/pick_cube")
    p.add_argument("--epochs", type=int, default=20)
    p.add_argument("--max-steps", type=int, default=None, help="cap on gradient steps")
    p.add_argument("--batch-size", type=int, default=None)
    p.add_argument("--num-data-workers", type=int, default=0)
    p.add_argument("--learning-rate", type=float, default=1e-4)
    p.add_argument("--weight-decay", type=float, default=1e-6)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--device", default="cpu")
    args = p.parse_args()
    cfg = {"epochs": args.epochs, "lr": args.learning_rate, "weight_decay": args.weight_decay,
           "num_workers": args.num_data_workers, "seed": args.seed, "device": args.device,
           "output_dir": args.output_dir}
    if args.batch_size:
        cfg["batch_size"] = args.batch_size
    if args.max_steps:
        cfg["max_steps"] = args.max_steps
    path = Policy.from_backend("diffusion").train(args.dataset_path, cfg)
    print(f"checkpoint: {path}")


if __name__ == "__main__":
    main()
