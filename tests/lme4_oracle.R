# The lme4 side of the oracle test (tests/test_lme4_oracle.py): fits every model the report fits to one study's
# trial table and writes what lme4 finds as JSON.
#
#   Rscript tests/lme4_oracle.R TRIALS.csv OUT.json
#
# TRIALS.csv: participant, scene, condition (levels none, basic, full; none the reference), total_time, n_queries.
# Each fit: fixef, its SEs, variance components, logLik, isSingular; every fit is run to convergence (BOBYQA to
# rhoend = 1e-12 for lmer, 1e-10 for glmer), as the defaults stop early where the likelihood is flat. Poisson fits
# are made with the inner PIRLS solved to tolPwrss = 1e-13; their "se" come from lme4's own finite-difference
# Hessian (deriv12, step 1e-4) of its own deviance function, restarted from its last linear predictor until its
# value stops changing — glmer's PIRLS evaluates the log-determinant at the weights of the iteration before the
# last, from a fixed start, which no tolPwrss fully converges (see analysis/glmm.py). "se_glmer" holds glmer's
# vcov() of the same fit, "default" the fit with glmer's default settings, to show how far those are.
suppressMessages({ library(lme4); library(jsonlite) })
args <- commandArgs(trailingOnly = TRUE)
d <- read.csv(args[1], stringsAsFactors = FALSE)
d$condition <- factor(d$condition, levels = c("none", "basic", "full"))
d$participant <- factor(d$participant)
d$scene <- factor(d$scene)
d$log_time <- log(d$total_time)

varcomp <- function(m) {
  v <- as.data.frame(VarCorr(m))
  setNames(as.list(v$vcov), ifelse(v$grp == "Residual", "residual", v$grp))
}

describe <- function(m, reml = FALSE) {
  list(fixef = as.list(fixef(m)), se = as.list(sqrt(diag(as.matrix(vcov(m))))), varcomp = varcomp(m),
       logLik = as.numeric(logLik(m)), REMLcrit = if (reml) as.numeric(REMLcrit(m)) else NULL,
       df = attr(logLik(m), "df"), nobs = nobs(m), singular = isSingular(m))
}

CONVERGED <- glmerControl(optimizer = "bobyqa", tolPwrss = 1e-13, optCtrl = list(rhoend = 1e-10, maxfun = 1e5))

# lmer's default BOBYQA stops at ~1e-6 on θ, which in a flat likelihood (two scenes) leaves a variance ~1% off
LMM_CONVERGED <- lmerControl(optimizer = "bobyqa", optCtrl = list(rhoend = 1e-12, maxfun = 1e5))
lmm <- function(formula, reml = FALSE) describe(lmer(formula, d, REML = reml, control = LMM_CONVERGED), reml)
converged_se <- function(m, formula, n_agq) {
  devfun <- glmer(formula, d, family = poisson, nAGQ = n_agq, devFunOnly = TRUE)
  rho <- environment(devfun)
  rho$tolPwrss <- 1e-13
  restarted <- function(p) {
    last <- Inf
    for (i in 1:50) {
      value <- devfun(p)
      rho$lp0 <- as.numeric(rho$resp$eta)
      if (abs(value - last) < 1e-11) break
      last <- value
    }
    value
  }
  k <- length(getME(m, "theta"))
  h <- lme4:::deriv12(restarted, c(getME(m, "theta"), fixef(m)))$Hessian
  v <- tryCatch(2 * solve(h)[-seq_len(k), -seq_len(k), drop = FALSE], error = function(e) NULL)
  if (is.null(v) || any(!is.finite(diag(v))) || any(diag(v) <= 0)) return(NULL)
  as.list(setNames(sqrt(diag(v)), names(fixef(m))))
}

pois <- function(formula, n_agq = 1) {
  converged <- glmer(formula, d, family = poisson, nAGQ = n_agq, control = CONVERGED)
  fit <- describe(converged)
  fit$se_glmer <- fit$se
  fit$se <- converged_se(converged, formula, n_agq)
  c(fit, list(default = describe(glmer(formula, d, family = poisson, nAGQ = n_agq))))
}

out <- list(
  versions = list(R = R.version.string, lme4 = as.character(packageVersion("lme4"))),
  time_ml = lmm(total_time ~ condition + (1 | participant) + (1 | scene)),
  time_ml_null = lmm(total_time ~ 1 + (1 | participant) + (1 | scene)),
  time_reml = lmm(total_time ~ condition + (1 | participant) + (1 | scene), reml = TRUE),
  log_time_ml = lmm(log_time ~ condition + (1 | participant) + (1 | scene)),
  log_time_ml_null = lmm(log_time ~ 1 + (1 | participant) + (1 | scene)),
  queries = pois(n_queries ~ condition + (1 | participant) + (1 | scene)),
  queries_null = pois(n_queries ~ 1 + (1 | participant) + (1 | scene)),
  queries_laplace_participant = pois(n_queries ~ condition + (1 | participant)),
  queries_agq_participant = pois(n_queries ~ condition + (1 | participant), n_agq = 10)
)
write_json(out, args[2], digits = NA, auto_unbox = TRUE, null = "null", pretty = TRUE)
