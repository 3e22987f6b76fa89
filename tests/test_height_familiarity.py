"""The familiarity study's scores (lab/height/familiarity_study.py) on cases worked by hand."""
import numpy as np

from pixgraph_lab.height.familiarity_study import auc, distances


def test_auc_counts_the_ordered_pairs():
    assert auc([0, 0, 1, 1], [0.1, 0.2, 0.3, 0.4]) == 1.0
    assert auc([1, 1, 0, 0], [0.1, 0.2, 0.3, 0.4]) == 0.0
    # positives 0.25 and 0.5 against negatives 0.1, 0.3 and 0.5: pairs won 1 + 2 + a tie's half = 3.5 of 6
    assert auc([0, 1, 0, 1, 0], [0.1, 0.25, 0.3, 0.5, 0.5]) == 3.5 / 6


def test_distances_of_bank_rows_and_of_the_mean():
    rng = np.random.default_rng(1)
    bank = rng.normal(size=(200, 12)) * np.arange(1, 13) + 5.0      # features of different scales
    d = distances(bank, bank[:3], k=10, pca=4)
    assert np.allclose(d["knn1"], 0.0, atol=1e-5)                  # a bank row is its own nearest
    assert np.all(d["knn10"] > 0.5)
    assert np.allclose(d["cos_knn10"], 1.0 - np.sort(
        (bank[:3] / np.linalg.norm(bank[:3], axis=1, keepdims=True))
        @ (bank / np.linalg.norm(bank, axis=1, keepdims=True)).T, axis=1)[:, ::-1][:, :10].mean(1))
    centre = distances(bank, bank.mean(0, keepdims=True), pca=4)
    assert centre["maha4"][0] < 1e-6                                # the mean is at the centre
    # a point 3 standard deviations out along the bank's first principal axis: Mahalanobis 3
    z = (bank - bank.mean(0)) / bank.std(0)
    _, s, vt = np.linalg.svd(z, full_matrices=False)
    far = bank.mean(0) + 3.0 * (s[0] / np.sqrt(len(z))) * vt[0] * bank.std(0)
    assert abs(distances(bank, far[None], pca=4)["maha4"][0] - 3.0) < 1e-3
    assert distances(bank, far[None], pca=4)["pca_residual4"][0] < 1e-3
