"""The update step of DMfD, AWAC and SAC-LfD computes the same numbers as the reference code.

``REFERENCE`` holds the logged training values and parameter fingerprints of a few gradient
steps on a fixed seed, recorded with the straightforward implementation (separate critic
MLPs, one ``.item()`` per logged value and update, SB3's ``polyak_update``) before the
update step was made faster.  The fast implementation keeps the construction order of every
layer (so a seed gives the same initial weights) and the order of every random draw (so a
seed gives the same batches and the same sampled actions); any change to a loss, a target,
an optimiser step or the target-network update moves these numbers far beyond the float32
round-off that the tolerance allows for.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch as th
from stable_baselines3.common.logger import configure

from dmfd_toy_env import ToyPickPlaceEnv, collect_episodes
from lfd_agents import AWAC, BC, DMfD, SACLfD

th.set_num_threads(1)

REL = 1e-5  # float32 round-off of a few re-associated sums, compounded over 9 updates
ABS = 1e-6


def _online_rows(model, n: int, seed: int) -> None:
    """Add ``n`` random transitions to the online replay buffer (fixed generator)."""
    rng = np.random.default_rng(seed)
    obs_dim = model.observation_space.shape[0]
    act_dim = model.action_space.shape[0]
    for _ in range(n):
        model.replay_buffer.add(rng.normal(size=(1, obs_dim)).astype(np.float32),
                                rng.normal(size=(1, obs_dim)).astype(np.float32),
                                rng.uniform(-1, 1, (1, act_dim)).astype(np.float32),
                                rng.normal(size=1).astype(np.float32), (rng.random(1) < 0.1), [{}])


def _build(name: str):
    demos = collect_episodes(3, obs_mode="image" if name == "dmfd_image" else "state")
    kw = dict(buffer_size=400, batch_size=32, seed=0)
    arch = dict(net_arch=[64, 64])
    if name == "dmfd":
        return DMfD("MlpPolicy", ToyPickPlaceEnv(), demonstrations=demos, policy_kwargs=arch, **kw)
    if name == "dmfd_target_entropy_demo_ratio":
        model = DMfD("MlpPolicy", ToyPickPlaceEnv(), demonstrations=demos, policy_kwargs=arch, target_ent_coef=0.2,
                     demo_ratio=0.5, reward_scale=3.0, **kw)
        _online_rows(model, 100, seed=5)
        return model
    if name == "dmfd_image":
        return DMfD("CnnPolicy", ToyPickPlaceEnv(obs_mode="image"), demonstrations=demos,
                    policy_kwargs=dict(net_arch=[32, 32]), **kw)
    if name == "awac":
        return AWAC("MlpPolicy", ToyPickPlaceEnv(), demonstrations=demos, offline_steps=0, policy_kwargs=arch, **kw)
    if name == "sac_lfd":
        model = SACLfD("MlpPolicy", ToyPickPlaceEnv(), demonstrations=demos, policy_kwargs=arch, **kw)
        _online_rows(model, 50, seed=6)
        return model
    raise KeyError(name)


def _fingerprint(module: th.nn.Module) -> list[float]:
    """Layout-independent summary of a module's parameters: sum, sum of squares, sum of |x|."""
    flat = th.cat([p.detach().double().flatten() for p in module.parameters()])
    return [float(flat.sum()), float((flat ** 2).sum()), float(flat.abs().sum())]


def _trace_bc() -> dict[str, list[float]]:
    """BC: the loss of each of 3 epochs (3 batches each) and the final fingerprint."""
    model = BC("MlpPolicy", ToyPickPlaceEnv(), demonstrations=collect_episodes(3), batch_size=32,
               policy_kwargs=dict(net_arch=[64, 64]), seed=0)
    th.manual_seed(11)
    np.random.seed(11)
    out: dict[str, list[float]] = {"train/bc_loss": []}
    for _ in range(3):
        model.learn(epochs=1, log_interval=0)
        out["train/bc_loss"].append(float(model.logger.name_to_value["train/bc_loss"]))
    out["fp/actor"] = _fingerprint(model.policy)
    return out


def trace(name: str) -> dict[str, list[float]]:
    """Logged values after each of 6 single updates and one 3-update call, and final fingerprints."""
    if name == "bc":
        return _trace_bc()
    model = _build(name)
    model.set_logger(configure(None, []))
    th.manual_seed(11)
    np.random.seed(11)
    out: dict[str, list[float]] = {}
    for n in (1, 1, 1, 1, 1, 1, 3):
        model.train(n, model.batch_size)
        for key, value in sorted(model.logger.name_to_value.items()):
            if key.startswith("train/") and key != "train/n_updates":
                out.setdefault(key, []).append(float(value))
    out["fp/actor"] = _fingerprint(model.actor)
    out["fp/critic"] = _fingerprint(model.critic)
    out["fp/critic_target"] = _fingerprint(model.critic_target)
    g = th.Generator().manual_seed(3)
    if name != "dmfd_image":
        x = th.randn(5, model.observation_space.shape[0], generator=g)
        a = th.rand(5, model.action_space.shape[0], generator=g) * 2 - 1
        with th.no_grad():
            out["q/critic"] = th.cat(model.critic(x, a), dim=1).flatten().tolist()
            out["q/critic_target"] = th.cat(model.critic_target(x, a), dim=1).flatten().tolist()
    return out


# recorded with the reference implementation (python tests/test_train_equivalence.py)
REFERENCE: dict[str, dict[str, list[float]]] = {
    "dmfd": {
        "fp/actor": [-6.00912964435156, 46.56109677467937, 362.4043362526081],
        "fp/critic": [9.042926568225084, 92.12520820213368, 754.901229148636],
        "fp/critic_target": [8.405897304119208, 92.04822625084144, 754.6022452094239],
        "q/critic": [
            0.1334647536277771, 0.13668087124824524, 0.16753500699996948, 0.15150797367095947,
            0.12226933240890503, 0.13889099657535553, 0.1066996157169342, 0.2413349151611328,
            0.06013442203402519, 0.29038572311401367
        ],
        "q/critic_target": [
            0.087929368019104, 0.07394825667142868, 0.10863083600997925, 0.11979477852582932,
            0.09427099674940109, 0.11180813610553741, 0.06923076510429382, 0.2087216079235077,
            0.012629453092813492, 0.2542528212070465
        ],
        "train/actor_loss": [
            344.49688720703125, 346.8824157714844, 377.5801696777344, 374.3934020996094, 303.7248229980469,
            319.780517578125, 323.5188496907552
        ],
        "train/awr_loss": [
            382.5460510253906, 385.15667724609375, 419.27215576171875, 415.73468017578125, 337.204833984375,
            355.0774841308594, 359.2162577311198
        ],
        "train/critic_loss": [
            0.5616823434829712, 0.9676954746246338, 0.8439440727233887, 0.5280362963676453, 0.5987467765808105,
            0.5935871601104736, 0.4339279631773631
        ],
        "train/entropy_loss": [
            2.0543439388275146, 2.4143733978271484, 2.3522391319274902, 2.322045087814331, 2.4046480655670166,
            2.1078033447265625, 2.2423139413197837
        ],
        "train/learning_rate": [0.0003, 0.0003, 0.0003, 0.0003, 0.0003, 0.0003, 0.0003],
        "train/log_std": [
            -2.9995501041412354, -2.9990997314453125, -2.9986493587493896, -2.9981982707977295,
            -2.9977548122406006, -2.9973134994506836, -2.995990514755249
        ],
        "train/max_weight": [
            1.0172916650772095, 1.0168194770812988, 1.0158053636550903, 1.014299988746643, 1.018178105354309,
            1.009159803390503, 1.0168507099151611
        ],
    },
    "dmfd_target_entropy_demo_ratio": {
        "fp/actor": [-6.870211479712452, 47.10137463415008, 366.1691418136397],
        "fp/critic": [7.2809685506690585, 92.07075244608697, 754.5760271873769],
        "fp/critic_target": [8.369193855639992, 92.04706217796462, 754.5944951877497],
        "q/critic": [
            0.04066059738397598, 0.015002112835645676, 0.03629365935921669, 0.05785903334617615,
            0.059319499880075455, 0.08453981578350067, 0.034977447241544724, 0.15923874080181122,
            -0.028244271874427795, 0.2165035605430603
        ],
        "q/critic_target": [
            0.08552128076553345, 0.07092053443193436, 0.10550661385059357, 0.11751267313957214,
            0.09279128909111023, 0.11052846908569336, 0.06749415397644043, 0.2066805511713028,
            0.01060592383146286, 0.2526713013648987
        ],
        "train/actor_loss": [
            253.15000915527344, 261.50042724609375, 308.7449645996094, 291.7275085449219, 283.9612121582031,
            211.33065795898438, 254.9833221435547
        ],
        "train/awr_loss": [
            281.0485534667969, 290.28533935546875, 342.7853088378906, 323.8792724609375, 315.2388916015625,
            234.5712127685547, 283.05511474609375
        ],
        "train/critic_loss": [
            7.778347492218018, 13.18704605102539, 10.754623413085938, 9.144758224487305, 5.638930320739746,
            20.81539535522461, 10.820258776346842
        ],
        "train/entropy_loss": [
            2.063140869140625, 2.4360878467559814, 2.3819522857666016, 2.3616857528686523, 2.46213698387146,
            2.165640115737915, 2.337228536605835
        ],
        "train/learning_rate": [0.0003, 0.0003, 0.0003, 0.0003, 0.0003, 0.0003, 0.0003],
        "train/log_std": [
            -2.9995501041412354, -2.9990999698638916, -2.9986495971679688, -2.9981985092163086,
            -2.9977481365203857, -2.997307777404785, -2.995983123779297
        ],
        "train/max_weight": [
            1.0188977718353271, 1.024101734161377, 1.0303670167922974, 1.027811050415039, 1.0255335569381714,
            1.0133461952209473, 1.0336754322052002
        ],
    },
    "dmfd_image": {
        "fp/actor": [35.85095852389986, 288.2569147186571, 3441.981662855679],
        "fp/critic": [34.07370176756331, 307.96493031407863, 3650.669074087428],
        "fp/critic_target": [44.372118355856, 307.7552615763718, 3645.3452530054005],
        "train/actor_loss": [
            353.1404113769531, 336.12506103515625, 324.5016784667969, 308.83367919921875, 226.7286834716797,
            237.47865295410156, 218.49828592936197
        ],
        "train/awr_loss": [
            392.09954833984375, 373.2141418457031, 360.27569580078125, 342.893310546875, 251.64247131347656,
            263.6207275390625, 242.5063222249349
        ],
        "train/critic_loss": [
            0.509244441986084, 0.8515573740005493, 0.6980332136154175, 0.4310973584651947, 0.4982103109359741,
            0.4815135598182678, 0.37996528546015423
        ],
        "train/entropy_loss": [
            2.5081400871276855, 2.3231515884399414, 2.535571336746216, 2.297110080718994, 2.5045166015625,
            2.200000762939453, 2.4260093371073403
        ],
        "train/learning_rate": [0.0003, 0.0003, 0.0003, 0.0003, 0.0003, 0.0003, 0.0003],
        "train/log_std": [
            -2.9995501041412354, -2.999100685119629, -2.998652219772339, -2.9982059001922607,
            -2.997770071029663, -2.99733829498291, -2.996058464050293
        ],
        "train/max_weight": [
            1.017065167427063, 1.0080046653747559, 1.0060012340545654, 1.005902647972107, 1.0064395666122437,
            1.0055577754974365, 1.0088565349578857
        ],
    },
    "awac": {
        "fp/actor": [-6.009314563745647, 46.56113600825729, 362.4045326138239],
        "fp/critic": [9.169569836376468, 92.12666160100609, 754.921901179303],
        "fp/critic_target": [8.409167996216638, 92.04826003577104, 754.6028329496385],
        "q/critic": [
            0.13403010368347168, 0.1370304524898529, 0.1683584749698639, 0.15300682187080383,
            0.12323074787855148, 0.13970433175563812, 0.10755540430545807, 0.24263960123062134,
            0.060678258538246155, 0.2910095751285553
        ],
        "q/critic_target": [
            0.08794355392456055, 0.07395397871732712, 0.10865101963281631, 0.11983672529459,
            0.09430300444364548, 0.11183011531829834, 0.06925380229949951, 0.20875252783298492,
            0.012644737958908081, 0.25427019596099854
        ],
        "train/actor_loss": [
            382.55224609375, 385.1585693359375, 419.283935546875, 415.7467346191406, 337.2126159667969,
            355.0860900878906, 359.2348937988281
        ],
        "train/awr_loss": [
            382.55224609375, 385.1585693359375, 419.283935546875, 415.7467346191406, 337.2126159667969,
            355.0860900878906, 359.2348937988281
        ],
        "train/critic_loss": [
            0.5668500661849976, 0.9768430590629578, 0.8516082763671875, 0.5330334901809692, 0.6038970947265625,
            0.598625659942627, 0.43687506516774494
        ],
        "train/entropy_loss": [
            2.054307222366333, 2.414306879043579, 2.352147340774536, 2.321909189224243, 2.4044837951660156,
            2.1075751781463623, 2.242005189259847
        ],
        "train/learning_rate": [0.0003, 0.0003, 0.0003, 0.0003, 0.0003, 0.0003, 0.0003],
        "train/log_std": [
            -2.9995501041412354, -2.9990997314453125, -2.9986493587493896, -2.9981982707977295,
            -2.9977548122406006, -2.9973134994506836, -2.995990514755249
        ],
        "train/max_weight": [
            1.0174506902694702, 1.0170621871948242, 1.0160752534866333, 1.0145901441574097, 1.0185503959655762,
            1.0095185041427612, 1.0171796480814617
        ],
    },
    "sac_lfd": {
        "fp/actor": [-7.70008638552099, 48.27985406200783, 379.8156042792689],
        "fp/critic": [17.182170991029125, 91.83723095658786, 753.4635768395092],
        "fp/critic_target": [14.419831396242444, 91.6989474763397, 752.887524115502],
        "q/critic": [
            0.09319363534450531, 0.20937758684158325, 0.07190772891044617, 0.3035464584827423,
            0.11460569500923157, 0.2511485815048218, 0.08749059587717056, 0.303092360496521,
            0.20666493475437164, 0.27387526631355286
        ],
        "q/critic_target": [
            0.013240113854408264, 0.11623451113700867, -0.006433039903640747, 0.22285987436771393,
            0.04963357746601105, 0.1758841574192047, -0.009858325123786926, 0.2288721203804016,
            0.10939446091651917, 0.19171033799648285
        ],
        "train/actor_loss": [
            -1.949307918548584, -1.9091047048568726, -2.157808303833008, -1.9978662729263306,
            -2.0085768699645996, -1.8133556842803955, -1.9480340878168743
        ],
        "train/critic_loss": [
            2.9750776290893555, 3.7968714237213135, 4.157777309417725, 3.954833745956421, 4.262210845947266,
            3.5418484210968018, 3.993072748184204
        ],
        "train/ent_coef": [
            1.0, 0.9997000694274902, 0.99940025806427, 0.9991002082824707, 0.9988003373146057,
            0.9985005855560303, 0.9979033470153809
        ],
        "train/ent_coef_loss": [
            0.0, -0.0014545292360708117, -0.003046380588784814, -0.004442219156771898, -0.005912174005061388,
            -0.0070814527571201324, -0.010164848528802395
        ],
        "train/learning_rate": [0.0003, 0.0003, 0.0003, 0.0003, 0.0003, 0.0003, 0.0003],
    },
    "bc": {
        "fp/actor": [-4.596903201600071, 47.3275365662675, 367.1177048231475],
        "train/bc_loss": [0.6436807513237, 0.5890331864356995, 0.539328396320343],
    },
}


CASES = ["dmfd", "dmfd_target_entropy_demo_ratio", "dmfd_image", "awac", "sac_lfd", "bc"]


@pytest.mark.parametrize("name", CASES)
def test_update_step_reproduces_reference_values(name):
    got = trace(name)
    ref = REFERENCE[name]
    assert sorted(got) == sorted(ref)
    for key, values in ref.items():
        np.testing.assert_allclose(got[key], values, rtol=REL, atol=ABS, err_msg=f"{name} {key}")


if __name__ == "__main__":  # print the reference table (run with the reference implementation)
    import json

    print(json.dumps({n: trace(n) for n in CASES}, indent=1))


# ------------------------------------------------------------------------------ fused critics
def _critics(width: int = 16, n_critics: int = 2):
    from gymnasium import spaces
    from stable_baselines3.common.policies import ContinuousCritic
    from stable_baselines3.common.torch_layers import FlattenExtractor

    from lfd_agents.networks import EnsembleCritic

    obs_space, act_space = spaces.Box(-1, 1, (5,), np.float32), spaces.Box(-1, 1, (3,), np.float32)
    th.manual_seed(0)
    sb3 = ContinuousCritic(obs_space, act_space, [width, width], FlattenExtractor(obs_space), 5,
                           n_critics=n_critics, share_features_extractor=False)
    th.manual_seed(0)
    fused = EnsembleCritic(obs_space, act_space, [width, width], FlattenExtractor(obs_space), 5, n_critics=n_critics)
    return sb3, fused


def _batch(seed: int = 0):
    g = th.Generator().manual_seed(seed)
    return th.randn(64, 5, generator=g), th.rand(64, 3, generator=g) * 2 - 1, th.randn(64, 1, generator=g)


@pytest.mark.parametrize("n_critics", [1, 2, 3])
def test_ensemble_critic_has_sb3_initial_weights_outputs_and_gradients(n_critics):
    sb3, fused = _critics(n_critics=n_critics)
    obs, act, y = _batch()
    act_a, act_b = act.clone().requires_grad_(True), act.clone().requires_grad_(True)
    q_sb3, q_fused = sb3(obs, act_a), fused(obs, act_b)
    assert len(q_fused) == n_critics and q_fused[0].shape == (64, 1)
    for a, b in zip(q_sb3, q_fused):
        th.testing.assert_close(a, b, rtol=1e-6, atol=1e-6)
    th.testing.assert_close(sb3.q1_forward(obs, act), fused.q1_forward(obs, act), rtol=1e-6, atol=1e-6)
    sum(((q - y) ** 2).mean() for q in q_sb3).backward()
    sum(((q - y) ** 2).mean() for q in q_fused).backward()
    th.testing.assert_close(act_a.grad, act_b.grad, rtol=1e-5, atol=1e-7)
    for j, k in enumerate((0, 2, 4)):  # Linear layers of each SB3 Sequential
        for i in range(n_critics):
            lin = getattr(sb3, f"qf{i}")[k]
            th.testing.assert_close(lin.weight.grad.t(), getattr(fused, f"w{j}").grad[i], rtol=1e-5, atol=1e-7)
            th.testing.assert_close(lin.bias.grad, getattr(fused, f"b{j}").grad[i, 0], rtol=1e-5, atol=1e-7)


def test_sb3_critic_state_and_adam_state_load_into_the_ensemble_and_training_continues_identically():
    """Files saved when the critics were SB3 ``ContinuousCritic``s: weights (state-dict hook) and
    Adam moments (``_ensemble_optimizer_state``) are re-laid out, and the next steps agree."""
    from lfd_agents.dmfd import _ensemble_optimizer_state

    sb3, fused = _critics()
    opt_sb3 = th.optim.Adam(sb3.parameters(), lr=1e-2)

    def step(critic, opt, seed):
        obs, act, y = _batch(seed)
        opt.zero_grad()
        sum(((q - y) ** 2).mean() for q in critic(obs, act)).backward()
        opt.step()

    for seed in range(3):  # weights and moments move away from the shared initialisation
        step(sb3, opt_sb3, seed)
    fused.load_state_dict(sb3.state_dict())
    opt_fused = th.optim.Adam(fused.parameters(), lr=1e-2, fused=True)
    opt_fused.load_state_dict(_ensemble_optimizer_state(opt_sb3.state_dict(), fused, opt_fused.state_dict()))
    assert opt_fused.param_groups[0]["fused"] is True
    for seed in range(3, 6):
        step(sb3, opt_sb3, seed)
        step(fused, opt_fused, seed)
    obs, act, _ = _batch(9)
    for a, b in zip(sb3(obs, act), fused(obs, act)):
        th.testing.assert_close(a, b, rtol=1e-5, atol=1e-6)
