"""``newton-lab tasks``, ``render`` and ``teleop``: the commands over one env (their arguments and checks:
``newton_lab.commands.env`` and ``newton_lab.commands.teleop``)."""

from __future__ import annotations

import json

from ..commands import RenderArgs, TasksArgs, TeleopArgs
from ..task_api.registry import list_tasks, lookup
from .workflow import rerun_hook


def list_task_ids(args: TasksArgs) -> int:
    from .. import tasks as _registered  # noqa: F401  deferred: registering the tasks imports Warp

    for task_id in list_tasks():
        print(f"{task_id}\t{lookup(task_id).description}")
    return 0


def render(args: RenderArgs) -> int:
    from PIL import Image  # deferred: only this command writes pictures

    from ..agents import expert_agent  # deferred: Warp/Newton are slow to import
    from ..datasets.files.output_paths import output_path  # deferred: datasets imports h5py and zarr (~1 s)
    from ..envs import make_env  # deferred: Warp/Newton are slow to import
    from ..envs.cameras import picture  # deferred: Warp/Newton are slow to import
    from ..envs.perturb import perturb_env, scene_axes  # deferred: Warp/Newton are slow to import

    view = {"data": ("rgb", "depth", "segmentation")}
    if args.resolution:
        view["resolution"] = tuple(args.resolution)
    perturbation = args.perturbation()
    env = make_env(args.task, **args.env_kwargs(), cameras={args.camera: view}, **scene_axes(perturbation))
    if perturbation:
        perturb_env(env, perturbation, seed=args.seed)
        env.reseed(args.seed)  # the episode starts under it (objects resized, masses, frictions)
    if args.expert_steps:
        agent = expert_agent(env)
        for _ in range(args.expert_steps):
            env.step(agent.act(env))
    images = env.render()
    output_path(args.out)
    Image.fromarray(picture(images, args.camera)).save(args.out)
    cam, names = env.sensors.cameras.specs[args.camera], env.sensors.cameras.segmentation_names
    seen = images[f"{args.camera}_segmentation"][0].unique().tolist()
    print(
        json.dumps(
            {
                "task": args.task,
                "camera": args.camera,
                "resolution": [cam.width, cam.height],
                "visible": [names[i] for i in seen],
                **({"perturbation": perturbation} if perturbation else {}),
                "out": args.out,
            }
        )
    )
    return 0


def teleop(args: TeleopArgs) -> int:
    """Operator episodes, one at a time, each kept / dropped / the last (``agents.teleop.teleop_session``)."""
    from ..agents.teleop import TeleopAgent, teleop_session  # deferred: Warp/Newton are slow to import
    from ..envs import make_env  # deferred: Warp/Newton are slow to import

    agent = TeleopAgent.from_device(args.device, **args.agent_kwargs())
    try:
        env = make_env(args.task, **args.env_kwargs())
        hook, close = rerun_hook(args, env)
        try:
            summary = teleop_session(env, agent, on_step=hook, **args.session_kwargs())
        finally:
            close()
    finally:
        agent.close()
    lat = summary["latency"]
    print(
        f"latency device frame -> action applied: mean {lat['mean_ms']:.2f} ms, max {lat['max_ms']:.2f} ms "
        f"({lat.get('max_control_steps', 0):.2f} control steps) over {lat['frames']} frames"
    )
    print(json.dumps({"task": args.task, "device": args.device, **summary}))
    return 0
