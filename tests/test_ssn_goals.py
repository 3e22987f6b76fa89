"""lab/ssn/goals.py: the issue's goal table from per-sample evaluation rows."""
from pixgraph_lab.ssn import goals


def _row(method, rmse, ssim, rr, obj="urdf:1"):
    return {"method": method, "rmse": str(rmse), "ssim": str(ssim), "relative_radius": str(rr), "object": obj}


def test_goal_rows_compute_means_ratios_and_verdicts():
    rows = []
    for rr, obj in ((0.02, "urdf:1"), (0.4, "proc:arch")):
        rows += [_row("ssn", 0.03 if rr < 0.1 else 0.06, 0.95, rr, obj),
                 _row("soft:256", 0.05, 0.97, rr, obj), _row("soft:64", 0.05, 0.96, rr, obj),
                 _row("renderer_hard", 0.04, 0.9, rr, obj)]
    got = {g[0]: g for g in goals.goal_rows(rows, "ssn", ground=True)}
    g = got["RMSE <= 0.75 x soft:256"]
    assert abs(g[1] - 0.045) < 1e-12 and abs(g[3] - 0.9) < 1e-12 and g[4] == 2 and not g[5]
    assert not got["SSIM >= soft:256"][5]
    assert got["RMSE < soft:64, softness 0-0.05"][5] and not got["RMSE < soft:64, softness 0.3-1"][5]
    assert "RMSE < soft:64, softness 0.1-0.2" not in got            # empty bins are left out
    thin = got["thin open objects: RMSE <= 1.1 x soft:64"]
    assert thin[4] == 1 and abs(thin[3] - 1.2) < 1e-12 and not thin[5]
    assert not got["RMSE < renderer's hard shadow"][5]
    assert "**no**" in goals.markdown(rows, "ssn", "ground", True)
