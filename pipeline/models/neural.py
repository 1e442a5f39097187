"""Back-propagation (BP) neural network from temperatures to thermal error.

Source: Li Xingda, Gu Qunying, Li Zihan and Yang Jianguo, "Modeling for thermal error based on time
series-neural network", Modular Machine Tool & Automatic Manufacturing Technique 2015(9), 13-16
("the TS-BP paper"), section 1.2 and the experiment: a three-layer BP network whose inputs are the
key-point temperatures and whose output is the error, Sigmoid hidden neurons, topology 2-6-1 (two
bearing temperatures, 6 hidden, 1 output), training rate eta = 0.01, at most 6000 training epochs,
mean-squared-error goal 0.01. The weight update is plain gradient descent on the mean squared error,
W(m + 1) = W(m) - eta dE/dW (the paper's "correction factor" update; its equations are missing from
the capture).

Implemented as a compact numpy network trained by full-batch gradient descent (deterministic,
~0.2 s for 110 x 4 samples). Details the paper does not state, chosen as the common MATLAB
defaults such networks were built with: inputs and target min-max scaled to [-1, 1] on the
training data (``mapminmax``), the 0.01 goal applies to the MSE on that scaled target, linear
output neuron; weights start Glorot-uniform (MATLAB uses Nguyen-Widrow) from ``random_state``.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
from scipy.special import expit

from pipeline.models.base import TemperatureModel

logger = logging.getLogger(__name__)


def _minmax(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (centre, half-range) mapping ``values`` to [-1, 1]; constant -> half-range 1."""
    low, high = values.min(axis=0), values.max(axis=0)
    half = (high - low) / 2.0
    return (high + low) / 2.0, np.where(half > 0.0, half, 1.0)


class BackPropagationRegressor(TemperatureModel):
    """Inputs-H-1 back-propagation network with a sigmoid hidden layer (the TS-BP paper).

    Parameters
    ----------
    hidden_units : int, default 6
        Sigmoid neurons in the hidden layer.
    learning_rate : float, default 0.01
        Gradient-descent step eta.
    max_epochs : int, default 6000
        Most full-batch training epochs.
    tol : float, default 0.01
        Training goal: stop once the MSE on the [-1, 1]-scaled target is <= tol.
    random_state : int or None, default 0
        Seed of the initial weights.

    Attributes
    ----------
    weights_ : tuple of numpy.ndarray
        Hidden weights (m, H), hidden biases (H,), output weights (H,), output bias (1,).
    n_epochs_ : int
        Epochs run.
    loss_ : float
        Final training MSE on the scaled target.
    feature_names_in_ : numpy.ndarray, shape (m,)
        Input sensor columns, selected by name at predict time.
    chosen_params_ : dict
        ``epochs`` (int) and ``train_mse_scaled`` (float).
    """

    def __init__(
        self,
        hidden_units: int = 6,
        learning_rate: float = 0.01,
        max_epochs: int = 6000,
        tol: float = 0.01,
        random_state: int | None = 0,
    ):
        self.hidden_units = hidden_units
        self.learning_rate = learning_rate
        self.max_epochs = max_epochs
        self.tol = tol
        self.random_state = random_state

    def _check_params(self) -> None:
        """Raise ValueError unless the hidden units and epochs are >= 1 and the rate > 0."""
        if self.hidden_units < 1 or self.max_epochs < 1 or self.learning_rate <= 0:
            raise ValueError(
                "hidden_units and max_epochs must be >= 1 and learning_rate > 0, got "
                f"{self.hidden_units}, {self.max_epochs}, {self.learning_rate}"
            )

    def _fit(self, frame: pd.DataFrame, target: np.ndarray) -> None:
        """Train the network by full-batch gradient descent; rows are treated independently."""
        self.x_centre_, self.x_half_ = _minmax(frame.to_numpy())
        self.y_centre_, self.y_half_ = (float(v) for v in _minmax(target))
        inputs = (frame.to_numpy() - self.x_centre_) / self.x_half_
        output = (target - self.y_centre_) / self.y_half_
        self.weights_, self.n_epochs_, self.loss_ = self._train(inputs, output)
        self.feature_names_in_ = np.asarray(list(frame.columns), dtype=object)
        self.n_features_in_ = frame.shape[1]
        self.chosen_params_ = {"epochs": self.n_epochs_, "train_mse_scaled": self.loss_}
        logger.debug("BP fit: %s", self.chosen_params_)

    def _train(
        self, inputs: np.ndarray, output: np.ndarray
    ) -> tuple[tuple[np.ndarray, ...], int, float]:
        """Gradient descent on the MSE; returns (weights, epochs run, final MSE)."""
        rng = np.random.default_rng(self.random_state)
        n, m = inputs.shape
        h = self.hidden_units
        w1 = rng.uniform(-1.0, 1.0, (m, h)) * np.sqrt(6.0 / (m + h))
        b1 = np.zeros(h)
        w2 = rng.uniform(-1.0, 1.0, h) * np.sqrt(6.0 / (h + 1))
        b2 = np.zeros(1)
        step = self.learning_rate
        epoch = 0
        while True:
            hidden = expit(inputs @ w1 + b1)
            residual = hidden @ w2 + b2 - output
            mse = float(residual @ residual) / n
            if mse <= self.tol or epoch == self.max_epochs:
                return (w1, b1, w2, b2), epoch, mse
            epoch += 1
            grad_out = (2.0 / n) * residual
            grad_hidden = np.outer(grad_out, w2) * hidden * (1.0 - hidden)
            w2 = w2 - step * (hidden.T @ grad_out)
            b2 = b2 - step * grad_out.sum()
            w1 = w1 - step * (inputs.T @ grad_hidden)
            b1 = b1 - step * grad_hidden.sum(axis=0)

    def _predict(self, frame: pd.DataFrame) -> np.ndarray:
        """Run the trained network on the scaled inputs and scale its output back to um."""
        inputs = (frame.to_numpy() - self.x_centre_) / self.x_half_
        w1, b1, w2, b2 = self.weights_
        scaled = expit(inputs @ w1 + b1) @ w2 + b2
        return scaled * self.y_half_ + self.y_centre_
